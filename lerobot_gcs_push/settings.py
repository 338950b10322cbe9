"""What a resumed job may not change: the settings that decide what it computes, compared leaf by leaf.

`generate` (its work folder and its finished dataset) and `improve` (its state file) refuse a resume whose
settings differ from those the job was begun with, naming each difference.
"""

from __future__ import annotations


def leaves(d: dict, prefix: str = "") -> dict:
    """A nested dict as {"a.b": value}."""
    out = {}
    for k, v in d.items():
        out |= leaves(v, f"{prefix}{k}.") if isinstance(v, dict) else {f"{prefix}{k}": v}
    return out


def changed(held: dict, wanted: dict, implicit: dict | None = None, only_held: bool = False) -> dict[str, tuple]:
    """{leaf: (held, wanted)} for the settings that differ. `implicit`: what a file written before a field
    existed held without naming it. `only_held`: leaves the held settings do not name are not compared
    (fields a later version added whose old value `implicit` does not know)."""
    held, wanted = leaves((implicit or {}) | held), leaves(wanted)
    keys = [k for k in wanted if k in held] if only_held else list(wanted)
    return {k: (held.get(k), wanted[k]) for k in sorted(keys) if held.get(k) != wanted[k]}


def describe(diff: dict[str, tuple]) -> str:
    """`name: held -> wanted`, joined: for the one-line refusal."""
    return ", ".join(f"{k}: {a!r} -> {b!r}" for k, (a, b) in diff.items())
