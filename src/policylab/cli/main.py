"""The ``policylab`` command: problems, planning, learning and deep RL from a shell.

Bad input exits with code 2 and one line on stderr; an internal error exits with 1
(set ``POLICYLAB_DEBUG=1`` for the traceback).
"""

from __future__ import annotations

import os
import sys

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
    add_completion=False,
    pretty_exceptions_enable=False,
)

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


def main(argv: list[str] | None = None) -> None:
    """Entry point: run the app, turning policylab errors into exit code 2."""
    try:
        app(args=argv, standalone_mode=False)
    except PolicylabError as e:
        typer.echo(f"policylab: error: {e}", err=True)
        sys.exit(2)
    except typer.Exit as e:
        sys.exit(e.exit_code)
    except typer.Abort:
        typer.echo("Aborted.", err=True)
        sys.exit(1)
    except SystemExit:
        raise
    except Exception as e:
        if isinstance(e, _click_exception_types()):
            e.show()  # type: ignore[attr-defined]
            sys.exit(2)
        if os.environ.get("POLICYLAB_DEBUG"):
            raise
        typer.echo(f"policylab: internal error: {type(e).__name__}: {e}", err=True)
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
