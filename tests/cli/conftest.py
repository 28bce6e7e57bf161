"""Shared by the command-line tests: run ``policylab`` in this process."""

from __future__ import annotations

from collections.abc import Callable

import pytest

from policylab.cli.main import main

RunCLI = Callable[[list[str]], tuple[int, str, str]]


@pytest.fixture
def run_cli(capsys: pytest.CaptureFixture[str]) -> RunCLI:
    """``run_cli(argv)`` -> (exit code, stdout, stderr) of ``policylab ARGV``."""

    def run(argv: list[str]) -> tuple[int, str, str]:
        with pytest.raises(SystemExit) as exc:
            main(argv)
            raise SystemExit(0)
        out = capsys.readouterr()
        return int(exc.value.code or 0), out.out, out.err

    return run
