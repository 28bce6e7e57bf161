"""Where numba caches policylab's compiled kernels: a folder keyed by their whole source.

numba's on-disk cache (``@njit(cache=True)``) checks only the file that holds a cached
function. A kernel that calls a compiled helper from another file (the TD kernels call
``epsilon_greedy_prob`` of ``tabular/kernels.py``) inlines that helper, so editing the
helper alone would leave the kernel's cached machine code stale: the old helper would
keep running. An install that updates one file but not another has the same trap.

This module, imported before any compiled function of policylab is defined, sends
policylab's cached kernels (and only those) to a folder whose name is a hash of the
package version and of the source of every module that holds compiled code, together
with every policylab module those import. Any edit to any of them gives a new folder,
hence a fresh compilation; an unchanged install finds its kernels again.

The folder lives under

* ``$NUMBA_CACHE_DIR/policylab/`` when the user set ``NUMBA_CACHE_DIR``;
* else the per-user cache folder (``$XDG_CACHE_HOME`` or ``~/.cache`` on Linux,
  ``~/Library/Caches`` on macOS, ``%LOCALAPPDATA%`` on Windows) under
  ``policylab/numba/``; never inside the installed package (which may be read-only);
* else, if that cannot be written, the temporary folder.

Folders of other source versions are pruned on import: a folder is removed when it has
not been used for 7 days, or when it is not among the 16 most recently used and has not
been used for an hour (so that several checkouts used side by side keep theirs).
"""

from __future__ import annotations

import contextlib
import functools
import hashlib
import os
import re
import shutil
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numba
from numba.core import caching

__all__ = ["cache_dir", "source_key"]

_PACKAGE = Path(__file__).resolve().parent
#: ``from policylab.a import b, c`` (groups 1, and 2 or 3 with the names: in parentheses
#: over several lines, or on one line) or ``import policylab.a`` (group 4).
_IMPORT = re.compile(
    r"^[ \t]*(?:from\s+(policylab(?:\.\w+)*)\s+import[ \t]+(?:\(([^)]*)\)|([\w \t,]+))"
    r"|import\s+(policylab(?:\.\w+)*))",
    re.MULTILINE,
)
_VERSION = re.compile(r"^__version__\s*=\s*['\"]([^'\"]+)['\"]", re.MULTILINE)
_KEEP_RECENT = 16
_GRACE_S = 3600.0
_MAX_AGE_S = 7 * 24 * 3600.0


@functools.cache
def _module_file(name: str) -> Path | None:
    """The source file of a policylab module name, if it is one of the package's."""
    parts = name.split(".")[1:]
    base = _PACKAGE.joinpath(*parts)
    for cand in (base.with_suffix(".py"), base / "__init__.py"):
        if cand.is_file():
            return cand
    return None


def _compiled_sources() -> dict[Path, bytes]:
    """The modules that hold compiled code, and every policylab module they import.

    A module "holds compiled code" when its source mentions numba. The closure over
    imports catches helpers, constants and ``overload`` implementations that numba
    freezes into a kernel at compile time.
    """
    texts = {p: p.read_bytes() for p in _PACKAGE.rglob("*.py")}
    todo = [p for p, t in texts.items() if b"numba" in t and p != Path(__file__).resolve()]
    todo.append(_PACKAGE / "__init__.py")  # the version
    seen: dict[Path, bytes] = {}
    while todo:
        p = todo.pop()
        if p in seen or p not in texts:
            continue
        seen[p] = texts[p]
        for name, grouped, names, imported in _IMPORT.findall(texts[p].decode("utf-8", "replace")):
            name = name or imported
            # "from policylab.a.b import c" may name module c of package a.b.
            subs = [_module_file(f"{name}.{n}") for n in _names(grouped or names)]
            for cand in (_module_file(name), *subs):
                if cand is not None and cand not in seen:
                    todo.append(cand)
            parent = name
            while "." in parent:  # importing a.b.c runs a/__init__ and a/b/__init__
                parent = parent.rsplit(".", 1)[0]
                init = _module_file(parent)
                if init is not None and init not in seen:
                    todo.append(init)
    return seen


def _names(imported: str) -> list[str]:
    """The names of ``from ... import a, b as c, (d, e)``: a, b, d, e."""
    out = []
    for n in imported.replace("\n", " ").split(","):
        n = n.strip().split(" ")[0]
        if n:
            out.append(n)
    return out


def source_key() -> str:
    """``<version>-<hash>``: the package version and a hash of the compiled code's source."""
    sources = _compiled_sources()
    h = hashlib.sha256()
    h.update(f"numba {numba.__version__}\n".encode())
    for p in sorted(sources):
        h.update(p.relative_to(_PACKAGE).as_posix().encode() + b"\0")
        h.update(hashlib.sha256(sources[p]).digest())
    init = sources.get(_PACKAGE / "__init__.py", b"").decode("utf-8", "replace")
    m = _VERSION.search(init)
    version = m.group(1) if m else "0"
    return f"{version}-{h.hexdigest()[:16]}"


def _user_cache_root() -> Path:
    if sys.platform == "win32":
        base = os.environ.get("LOCALAPPDATA") or str(Path.home() / "AppData" / "Local")
    elif sys.platform == "darwin":
        base = str(Path.home() / "Library" / "Caches")
    else:
        base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "policylab" / "numba"


def _writable(path: Path) -> bool:
    try:
        path.mkdir(parents=True, exist_ok=True)
        tempfile.TemporaryFile(dir=path).close()
    except OSError:
        return False
    return True


def _prune(parent: Path, keep: Path) -> None:
    """Remove the folders of other source versions that are no longer used."""
    now = time.time()
    try:
        others = [(p.stat().st_mtime, p) for p in parent.iterdir() if p.is_dir() and p != keep]
    except OSError:
        return
    others.sort(reverse=True)
    for rank, (mtime, p) in enumerate(others):
        idle = now - mtime
        if idle > _MAX_AGE_S or (rank >= _KEEP_RECENT - 1 and idle > _GRACE_S):
            shutil.rmtree(p, ignore_errors=True)


def _choose_dir() -> Path:
    key = source_key()
    user = str(getattr(numba.config, "CACHE_DIR", "") or "")
    roots = [Path(user) / "policylab"] if user else [_user_cache_root()]
    roots.append(Path(tempfile.gettempdir()) / f"policylab-numba-{_uid()}")
    for root in roots:
        path = root / key
        if _writable(path):
            with contextlib.suppress(OSError):
                os.utime(path)  # "last used", read by the pruning
            _prune(root, path)
            return path
    return roots[-1] / key


def _uid() -> str:
    getuid = getattr(os, "getuid", None)
    return str(getuid()) if getuid is not None else os.environ.get("USERNAME", "user")


_CACHE_DIR = _choose_dir()


def cache_dir() -> Path:
    """The folder that holds policylab's compiled kernels for this source version."""
    return _CACHE_DIR


class _PolicylabCacheLocator(caching.UserProvidedCacheLocator):
    """numba's user-folder locator, pointed at :func:`cache_dir`, for policylab files only."""

    def __init__(self, py_func: Any, py_file: str) -> None:
        super().__init__(py_func, py_file)  # type: ignore[no-untyped-call]
        sub = self.get_suitable_cache_subpath(py_file)  # type: ignore[no-untyped-call]
        self._cache_path = str(_CACHE_DIR / sub)

    @classmethod
    def from_function(cls, py_func: Any, py_file: str) -> Any:
        try:
            Path(py_file).resolve().relative_to(_PACKAGE)
        except (OSError, ValueError):
            return None  # not policylab's: numba's own locators decide
        locator = cls(py_func, py_file)
        try:
            locator.ensure_cache_path()  # type: ignore[no-untyped-call]
        except OSError:
            return None  # cannot write there: numba's own locators decide
        return locator


def _install() -> None:
    locators = caching.CacheImpl._locator_classes
    if not any(c.__name__ == _PolicylabCacheLocator.__name__ for c in locators):
        locators.insert(0, _PolicylabCacheLocator)


_install()
