"""Run every code block of the documentation, and put the figures it draws into the site.

One module does both jobs, so that what the site shows is what the tests check:

- as an MkDocs hook (``hooks:`` in ``mkdocs.yml``), :func:`on_files` runs each page's
  code blocks in order, in one namespace per page, in a fresh temporary folder, and adds
  every file the code writes under ``figures/`` to the site beside the page (a page
  ``tutorials/returns.md`` that saves ``figures/loop.png`` shows it as
  ``![...](figures/loop.png)``). A block that raises, or a ``pycon`` block whose printed
  output differs from what the page claims, fails the build with the page and line;
- the tests (``tests/docs``) run the strict build, and call :func:`run_blocks` on each
  Python block of the README.

Blocks that run:

- ```` ```python ````: executed as a script;
- ```` ```pycon ````: an interactive session, checked like a doctest (``...`` matches
  anything, whitespace is normalised): every output the page shows is asserted;
- ```` ```bash ```` preceded by the line ``<!-- test: run -->``: each command line runs and
  must exit 0 (a plain ``policylab ...`` line in this process, through the command's
  own entry point; any other line in ``sh``, with the interpreter's folder on PATH).

Other fences (``text``, ``toml``, ``bash`` without the marker) are shown only.
"""

from __future__ import annotations

import contextlib
import dataclasses
import doctest
import io
import logging
import os
import re
import shlex
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

log = logging.getLogger("mkdocs.hooks.runpages")

RUN_MARKER = "<!-- test: run -->"
_FENCE = re.compile(r"^(?P<indent>[ \t]*)(?P<fence>`{3,}|~{3,})[ \t]*(?P<info>[^\n`]*)$")
_DOCTEST_FLAGS = doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE


@dataclasses.dataclass(frozen=True)
class Block:
    """One fenced code block: its language, its text (dedented) and where it starts."""

    lang: str
    code: str
    line: int
    run_marker: bool = False

    @property
    def runs(self) -> bool:
        """Whether this block is executed (python, pycon, or a marked bash block)."""
        return self.lang in ("python", "py", "pycon") or (
            self.lang in ("bash", "sh", "console") and self.run_marker
        )


@dataclasses.dataclass
class PageRun:
    """What running one page gave: blocks run, files written under ``figures/``, seconds."""

    blocks: int
    figures: dict[str, bytes]
    seconds: float
    namespace: dict[str, Any] = dataclasses.field(default_factory=dict, repr=False)


class BlockError(Exception):
    """A code block of a page failed; the message names the page and the line."""


def extract_blocks(text: str) -> list[Block]:
    """Every fenced code block of a Markdown text, in order (nested fences included)."""
    lines = text.splitlines()
    blocks: list[Block] = []
    i = 0
    while i < len(lines):
        m = _FENCE.match(lines[i])
        if not m:
            i += 1
            continue
        indent, fence = m.group("indent"), m.group("fence")
        lang = m.group("info").strip().split(" ")[0].lstrip("{.").rstrip("}").lower()
        prev = next((ln.strip() for ln in reversed(lines[:i]) if ln.strip()), "")
        body: list[str] = []
        j = i + 1
        while j < len(lines):
            stripped = lines[j].strip()
            if stripped.startswith(fence[0] * len(fence)) and set(stripped) == {fence[0]}:
                break
            body.append(lines[j][len(indent) :] if lines[j].startswith(indent) else lines[j])
            j += 1
        blocks.append(Block(lang, "\n".join(body) + "\n", i + 1, prev == RUN_MARKER))
        i = j + 1
    return blocks


def _run_python(block: Block, ns: dict[str, Any], where: str) -> None:
    code = compile(block.code, f"{where}:{block.line}", "exec")
    exec(code, ns)


def _run_pycon(block: Block, ns: dict[str, Any], where: str) -> None:
    parser = doctest.DocTestParser()
    test = parser.get_doctest(block.code, ns, f"{where}:{block.line}", where, block.line)
    out = io.StringIO()
    runner = doctest.DocTestRunner(optionflags=_DOCTEST_FLAGS, verbose=False)
    runner.run(test, out=out.write, clear_globs=False)
    ns.update(test.globs)  # DocTest runs on a copy of the namespace
    if runner.failures:
        raise BlockError(out.getvalue())


def run_policylab(argv: list[str]) -> tuple[int, str]:
    """Run ``policylab ARGV`` in this process (no interpreter start-up); (exit code, output)."""
    from policylab.cli.main import main

    out = io.StringIO()
    code: int | str | None = 0
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(out):
        try:
            main(argv)
        except SystemExit as exc:
            code = exc.code
    return (code if isinstance(code, int) else 1), out.getvalue()


def _run_shell(block: Block, env: dict[str, str], where: str) -> None:
    """Run each command line; a plain ``policylab ...`` line runs in-process, others in sh."""
    for n, cmd in enumerate(block.code.splitlines()):
        cmd = cmd.split(" #", 1)[0].strip()
        if not cmd or cmd.startswith("#"):
            continue
        argv = shlex.split(cmd)
        if argv[0] == "policylab" and not set(cmd) & set("|<>;&$`"):
            code, output = run_policylab(argv[1:])
        else:
            proc = subprocess.run(
                cmd, shell=True, env=env, capture_output=True, text=True, timeout=300, check=False
            )
            code, output = proc.returncode, proc.stdout + proc.stderr
        if code != 0:
            raise BlockError(
                f"{where}:{block.line + n + 1}: `{cmd}` exited {code}\n{output[-3000:]}"
            )


def _shell_env() -> dict[str, str]:
    env = dict(os.environ)
    env["PATH"] = f"{Path(sys.executable).parent}{os.pathsep}{env.get('PATH', '')}"
    env["MPLBACKEND"] = "Agg"
    return env


def run_markdown(
    text: str, where: str, *, workdir: Path | None = None, replace: dict[str, str] | None = None
) -> PageRun:
    """Run the code blocks of one Markdown text in order, in one namespace.

    See :func:`run_blocks` for the arguments (``text`` is the Markdown source).
    """
    return run_blocks(extract_blocks(text), where, workdir=workdir, replace=replace)


def run_blocks(
    blocks: list[Block],
    where: str,
    *,
    workdir: Path | None = None,
    replace: dict[str, str] | None = None,
) -> PageRun:
    """Run code blocks in order, in one namespace (blocks that do not run are skipped).

    Args:
        blocks: The blocks, from :func:`extract_blocks`.
        where: A name for messages (the page's path).
        workdir: The folder the code runs in (a new temporary folder when None); the
            files the code writes under ``workdir/figures`` are returned.
        replace: Literal text substitutions applied to each block before it runs (the
            README test uses it to run the README's full-budget examples on small
            budgets); a key that no block contains is an error, so none goes stale.

    Returns:
        The number of blocks run, the figures written, the seconds taken, and the
        namespace the blocks ran in.

    Raises:
        BlockError: A block raised, a shown output differs, or a command failed.
    """
    import matplotlib

    matplotlib.use("Agg")
    blocks = [b for b in blocks if b.runs]
    unused = set(replace or {})
    if replace:
        patched = []
        for b in blocks:
            code = b.code
            for old, new in replace.items():
                if old in code:
                    unused.discard(old)
                    code = code.replace(old, new)
            patched.append(dataclasses.replace(b, code=code))
        blocks = patched
    if unused:
        raise BlockError(f"{where}: no code block contains {sorted(unused)}")
    t0 = time.perf_counter()
    with contextlib.ExitStack() as stack:
        if workdir is None:
            workdir = Path(stack.enter_context(tempfile.TemporaryDirectory(prefix="pl-docs-")))
        env = _shell_env()
        ns: dict[str, Any] = {"__name__": "__docs__"}
        old_cwd = Path.cwd()
        os.chdir(workdir)
        try:
            for b in blocks:
                try:
                    if b.lang == "pycon":
                        _run_pycon(b, ns, where)
                    elif b.lang in ("python", "py"):
                        _run_python(b, ns, where)
                    else:
                        _run_shell(b, env, where)
                except BlockError:
                    raise
                except BaseException as exc:
                    raise BlockError(
                        f"{where}:{b.line}: the {b.lang} block raised {type(exc).__name__}: {exc}"
                    ) from exc
                finally:
                    import matplotlib.pyplot as plt

                    plt.close("all")
        finally:
            os.chdir(old_cwd)
        figdir = workdir / "figures"
        figures = (
            {
                p.relative_to(figdir).as_posix(): p.read_bytes()
                for p in figdir.rglob("*")
                if p.is_file()
            }
            if figdir.is_dir()
            else {}
        )
    return PageRun(len(blocks), figures, time.perf_counter() - t0, ns)


# --------------------------------------------------------------------------- MkDocs hook


def on_files(files: Any, config: Any) -> Any:
    """Run every page's code blocks; add the figures they write to the site."""
    from mkdocs.exceptions import PluginError
    from mkdocs.structure.files import File

    t0 = time.perf_counter()
    n_blocks = n_pages = 0
    produced: dict[str, str] = {}
    for f in list(files.documentation_pages()):
        text = Path(f.abs_src_path).read_text(encoding="utf-8")
        if not any(b.runs for b in extract_blocks(text)):
            continue
        try:
            run = run_markdown(text, f.src_uri)
        except BlockError as exc:
            raise PluginError(f"a code block of docs/{f.src_uri} failed:\n{exc}") from exc
        n_blocks += run.blocks
        n_pages += 1
        base = Path(f.src_uri).parent
        for name, data in run.figures.items():
            uri = (base / "figures" / name).as_posix()
            if uri in produced:
                raise PluginError(f"{f.src_uri} and {produced[uri]} both draw {uri}")
            produced[uri] = f.src_uri
            files.append(File.generated(config, uri, content=data))
        log.info("ran %d blocks of %s in %.1f s", run.blocks, f.src_uri, run.seconds)
    log.info(
        "policylab docs: ran %d code blocks on %d pages, %d figures, in %.1f s",
        n_blocks,
        n_pages,
        len(produced),
        time.perf_counter() - t0,
    )
    return files


_MATH = re.compile(
    r'<(?P<tag>span|div) class="arithmatex">\s*\\(?P<open>[(\[])(?P<tex>.*?)\\[)\]]\s*</(?P=tag)>',
    re.S,
)


_ROLE = re.compile(
    r":(?:py:)?(?:class|func|meth|mod|attr|data|obj|exc|const):<code>(?P<tilde>~?)(?P<name>[\w.]+)</code>"
)


def _canonical(path: str) -> str:
    """Where an object is defined (``policylab.FiniteMDP`` -> ``policylab.mdp.finite.FiniteMDP``).

    The API pages document each object under the package that exports it and register
    its defining module's path too; a path that does not import is returned as it is.
    """
    import importlib

    parts = path.split(".")
    for i in range(len(parts) - 1, 0, -1):
        try:
            obj: Any = importlib.import_module(".".join(parts[:i]))
        except ImportError:
            continue
        try:
            for attr in parts[i:]:
                obj = getattr(obj, attr)
        except AttributeError:
            return path
        module, qualname = getattr(obj, "__module__", None), getattr(obj, "__qualname__", None)
        if isinstance(module, str) and isinstance(qualname, str) and "<" not in qualname:
            return f"{module}.{qualname}"
        return path
    return path


def _cross_references(html: str, page: Any) -> str:
    """Turn the Sphinx roles of docstrings (``:class:`~policylab.FiniteMDP```) into links.

    Each becomes an optional mkdocs-autorefs reference: a link where the name is in the
    API reference, plain code where it is not. A bare name on an API page is looked up in
    that page's module.
    """
    module = None
    parts = Path(page.file.src_uri).with_suffix("").parts
    if parts[:2] == ("reference", "api") and len(parts) == 3 and parts[2] != "policylab":
        module = f"policylab.{parts[2]}"

    def link(m: re.Match[str]) -> str:
        name = m.group("name").lstrip(".")
        title = name.rsplit(".", 1)[-1] if m.group("tilde") else name
        ident = name if "." in name or module is None else f"{module}.{name}"
        return f'<autoref identifier="{_canonical(ident)}" optional><code>{title}</code></autoref>'

    return _ROLE.sub(link, html)


def on_page_content(html: str, page: Any, config: Any, files: Any) -> str:
    """Link the docstrings' cross-references; turn equations into MathML (no script)."""
    import html as html_lib

    from latex2mathml.converter import convert

    def to_mathml(m: re.Match[str]) -> str:
        tex = html_lib.unescape(m.group("tex")).strip()
        display = "block" if m.group("open") == "[" else "inline"
        return convert(tex, display=display)

    return _MATH.sub(to_mathml, _cross_references(html, page))
