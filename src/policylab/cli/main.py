"""The ``policylab`` command: problems, planning, learning and deep RL from a shell.

Bad input (a policylab error, a usage error, a path that cannot be read or written)
exits with code 2 and one line on stderr; an internal error exits with 1 (set
``POLICYLAB_DEBUG=1`` for the traceback); Ctrl-C exits with 130. ``policylab --version``
prints the version, and ``--install-completion`` sets up shell completion.
"""

from __future__ import annotations

import os
import sys
from typing import Annotated, Any

import typer

from policylab.cli.problems_cmd import problems_command, show_command
from policylab.cli.tour import tour_command
from policylab.exceptions import PolicylabError

__all__ = ["app", "main"]

app = typer.Typer(
    name="policylab",
    help=(
        "Reinforcement learning from finite MDPs to deep RL. Problems are named by their "
        "builder with hyphens (recycling-robot, mountain-gridworld, slippery-gridworld, ...) "
        "or by a Gymnasium id whose env exposes a model P (FrozenLake-v1, CliffWalking-v1)."
    ),
    no_args_is_help=True,
    add_completion=True,
    pretty_exceptions_enable=False,
)


def _version(value: bool) -> None:
    if value:
        from policylab import __version__

        typer.echo(f"policylab {__version__}")
        raise typer.Exit()


@app.callback()
def _root(
    version: Annotated[
        bool,
        typer.Option(
            "--version",
            callback=_version,
            is_eager=True,
            help="Print the version and exit.",
        ),
    ] = False,
) -> None:
    """Reinforcement learning from finite MDPs to deep RL."""


app.command("problems")(problems_command)
app.command("show")(show_command)
app.command("tour")(tour_command)


def _register_layer_commands() -> None:
    """Add the subcommands of the other layers: every ``policylab.cli.cmd_*`` module."""
    import importlib
    import pkgutil

    import policylab.cli as pkg

    for info in sorted(pkgutil.iter_modules(pkg.__path__), key=lambda m: m.name):
        if info.name.startswith("cmd_"):
            importlib.import_module(f"policylab.cli.{info.name}").register(app)


_register_layer_commands()


def _flags_show_no_type() -> None:
    """Help lists a flag as ``--json``, not ``--json <bool>``: a flag takes no value."""
    from typer.core import TyperOption

    if getattr(TyperOption.display_type_rich, "_policylab", False):
        return
    original = TyperOption.display_type_rich

    def display_type_rich(self: Any, ctx: Any) -> str | None:
        if self.is_flag:
            return None
        return original(self, ctx)

    display_type_rich._policylab = True  # type: ignore[attr-defined]
    TyperOption.display_type_rich = display_type_rich  # type: ignore[method-assign]


_flags_show_no_type()


def _one_line(text: str) -> str:
    return " ".join(str(text).split())


def _given(param: Any, argv: list[str]) -> str | None:
    """The value the user wrote for an option (``--episodes nan`` -> ``nan``), if found."""
    opts = [o for o in getattr(param, "opts", []) if o.startswith("-")]
    for i, tok in enumerate(argv):
        for o in opts:
            if tok == o and i + 1 < len(argv):
                return argv[i + 1]
            if tok.startswith(o + "="):
                return tok[len(o) + 1 :]
    return None


def _usage_message(e: Any, argv: list[str]) -> str:
    """A usage error as one line: Click's message, the value given, where to find help."""
    msg = _one_line(e.format_message()).rstrip(".")
    given = _given(getattr(e, "param", None), argv)
    if given is not None:
        msg += f"; got {given!r}"
    ctx = getattr(e, "ctx", None)
    if ctx is not None:
        msg += f" (see '{ctx.command_path} --help')"
    return msg


def main(argv: list[str] | None = None) -> None:
    """Entry point: run the app; bad input exits 2 with one line on stderr."""
    args = list(sys.argv[1:] if argv is None else argv)
    try:
        app(args=args, standalone_mode=False, prog_name="policylab")
    except PolicylabError as e:
        typer.echo(f"policylab: error: {_one_line(str(e))}", err=True)
        sys.exit(2)
    except typer.Exit as e:
        sys.exit(e.exit_code)
    except typer.Abort:
        typer.echo("policylab: aborted", err=True)
        sys.exit(130)
    except KeyboardInterrupt:
        typer.echo("policylab: interrupted", err=True)
        sys.exit(130)
    except SystemExit:
        raise
    except MemoryError:
        typer.echo(
            "policylab: error: not enough memory for this input (fewer episodes, steps or states?)",
            err=True,
        )
        sys.exit(2)
    except OSError as e:
        if os.environ.get("POLICYLAB_DEBUG"):
            raise
        where = f" {str(e.filename)!r}" if e.filename is not None else ""
        typer.echo(f"policylab: error:{where} {e.strerror or _one_line(str(e))}", err=True)
        sys.exit(2)
    except Exception as e:
        if isinstance(e, _click_exception_types()):
            if type(e).__name__ == "NoArgsIsHelpError":  # the help is the answer (Click: exit 2)
                if e.format_message().strip():  # type: ignore[attr-defined]
                    typer.echo(e.format_message(), err=True)  # type: ignore[attr-defined]
                sys.exit(2)
            typer.echo(f"policylab: error: {_usage_message(e, args)}", err=True)
            sys.exit(int(getattr(e, "exit_code", 2)) or 2)
        if os.environ.get("POLICYLAB_DEBUG"):
            raise
        typer.echo(f"policylab: internal error: {type(e).__name__}: {_one_line(str(e))}", err=True)
        sys.exit(1)


def _click_exception_types() -> tuple[type[Exception], ...]:
    """Click's usage-error base classes: the copy newer typer versions bundle, and click's.

    Both are checked: with such a typer, the usage errors come from its bundled copy even
    when click itself is installed too (another package, such as mkdocs, may bring it).
    """
    import importlib

    found: list[type[Exception]] = []
    for module in ("typer._click.exceptions", "click.exceptions"):
        try:
            found.append(importlib.import_module(module).ClickException)
        except ImportError:
            continue
    return tuple(found)
