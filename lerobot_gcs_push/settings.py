"""What a resumed job may not change: the settings that decide what it computes, compared leaf by leaf.

`generate` (its work folder and its finished dataset) and `improve` (its state file) refuse a resume whose
settings differ from those the job was begun with, naming each difference. The shared configs nested in several
commands (`Shared`) keep their options' flat names, on the command line and in those records.
"""

from __future__ import annotations

import functools
from dataclasses import asdict, fields, replace
from typing import ClassVar


def check_choice(what: str, value, choices) -> str:
    """`value` if it is one of `choices`, else a ValueError that lists them."""
    if value not in choices:
        raise ValueError(f"unknown {what} {value!r}: choose one of {tuple(choices)}")
    return value


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


class Shared:
    """A config nested in several commands' (the starts, the output, the expert: one definition of each option)
    whose options keep the flat names users typed and records held before the nesting: `--seed` as well as
    `--starts.seed` on the command line (`flat_argv`), `seed=` in Python (`flat_options`), `seed` in a record
    (`flat_settings`). A flat name must say which config it means: `flat_names` refuses one that two hold.

    Defaults that differ between commands are None here, filled in by each command's config, because draccus
    builds a nested config from its class's defaults once any of its options is given: a command's own
    `default_factory` would hold only while none is."""

    # The option `--<field>=value` sets, if any: the expert's mode (`--expert=closed-loop`, as before).
    flat_value: ClassVar[str | None] = None


def _shared_fields(cls) -> dict[str, type]:
    """{field: class} of the shared configs nested in dataclass `cls` (each as `field(default_factory=Class)`)."""
    return {
        f.name: f.default_factory
        for f in fields(cls)
        if isinstance(f.default_factory, type) and issubclass(f.default_factory, Shared)
    }


def flat_names(cls) -> dict[str, tuple[str, str]]:
    """{flat name: (field, option)} for the options of the shared configs nested in dataclass `cls`."""
    own = {f.name for f in fields(cls)}
    out: dict[str, tuple[str, str]] = {}
    for name, sub in _shared_fields(cls).items():
        if sub.flat_value:
            out[name] = (name, sub.flat_value)
        for leaf in (f.name for f in fields(sub) if f.name != sub.flat_value):  # one flat name each
            if leaf in own or leaf in out:  # a definition error, caught by any test that parses the command
                raise TypeError(f"{cls.__name__}: the flat option {leaf!r} is ambiguous")
            out[leaf] = (name, leaf)
    return out


def flat_argv(cls, argv: list[str]) -> list[str]:
    """The command line with each flat option of a nested shared config spelled in full (`--seed=3` ->
    `--starts.seed=3`, `--expert open-loop` -> `--expert.mode open-loop`), as draccus parses it."""
    names = flat_names(cls)
    out = []
    for arg in argv:
        name, eq, value = arg[2:].partition("=")
        if arg.startswith("--") and name in names:
            arg = "--" + ".".join(names[name]) + eq + value
        out.append(arg)
    return out


def nest(cls, kwargs: dict) -> dict:
    """`kwargs` for dataclass `cls` with the flat names of its nested shared configs' options gathered into
    those configs: `seed=3` -> `starts=StartsConfig(seed=3)`, or onto a given `starts` (so that
    `dataclasses.replace(cfg, resume=True)` keeps the rest of `cfg.output`). The Python twin of `flat_argv`."""
    names, nested, own = flat_names(cls), {}, {}
    for k, v in kwargs.items():
        if k in names and not isinstance(v, Shared):
            field_name, leaf = names[k]
            nested.setdefault(field_name, {})[leaf] = v
        else:
            own[k] = v
    shared = _shared_fields(cls)
    for field_name, options in nested.items():
        given = own.get(field_name)
        own[field_name] = replace(given, **options) if given is not None else shared[field_name](**options)
    return own


def flat_options(cls):
    """Class decorator (outside @dataclass): `cls(seed=3, repo_id=...)` takes the flat names of its nested
    shared configs' options, as the command line does (`nest`): the Python API reads as it did."""
    init = cls.__init__

    @functools.wraps(init)
    def __init__(self, *args, **kwargs):
        init(self, *args, **nest(cls, kwargs))

    cls.__init__ = __init__
    return cls


def flat_settings(cfg) -> dict:
    """`asdict(cfg)` with its nested shared configs' options under their flat names (the mode `flat_value`
    under the field's own: `expert`), as records held them before the nesting."""
    out = asdict(cfg)
    for name, sub in _shared_fields(type(cfg)).items():
        nested = out.pop(name)
        if sub.flat_value:
            out[name] = nested.pop(sub.flat_value)
        out |= nested
    return out
