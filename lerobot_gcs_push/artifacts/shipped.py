"""Where the shipped policies and configs are, wherever a command runs.

The defaults name them as the repository holds them (`policies/diffusion_cpu`,
`configs/policy/diffusion_cpu.json`), so they read the same in the README and in a checkout. Run from any
other folder, such a path is found in the checkout the package was installed from (`make install`'s
editable install) or among the data files a wheel installs under `<prefix>/share/lerobot-gcs-push`. A
path that exists from the working folder is always taken as given, so any other policy or config works.
"""

from __future__ import annotations

import sys
from pathlib import Path

DATA_DIR = "share/lerobot-gcs-push"  # a wheel's data files (pyproject.toml's tool.setuptools.data-files)
# Only these are shipped: another relative path (outputs/..., say) is never looked up in the checkout.
SHIPPED = ("policies", "configs")


def roots() -> list[Path]:
    """Where shipped files are looked for: the checkout beside the package, then the wheel's data files."""
    return [Path(__file__).resolve().parents[2], Path(sys.prefix) / DATA_DIR]


def shipped_path(path: str) -> str:
    """`path` itself if it exists from the working folder (or is absolute, or not under policies/ or
    configs/); else the shipped file or folder of that name, if there is one; else `path` unchanged, for
    the caller's own error."""
    given = Path(path)
    if given.is_absolute() or given.exists() or not given.parts or given.parts[0] not in SHIPPED:
        return path
    for root in roots():
        if (root / given).exists():
            return str(root / given)
    return path
