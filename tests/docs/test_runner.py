"""The block runner itself: it finds every block, runs them in order, and can fail."""

from __future__ import annotations

import textwrap

import pytest
from tests.docs._load import runpages

rp = runpages()

PAGE = textwrap.dedent(
    """\
    # A page

    ```python
    x = 2
    ```

    Text.

    ```pycon
    >>> x * 3
    6
    >>> [x] * 2
    [2, 2]
    ```

    ```text
    not code
    ```

    ```bash
    policylab --help   # shown only: no marker
    ```

    !!! note
        ```python
        y = x + 1
        ```

    <!-- test: run -->
    ```bash
    policylab problems
    ```
    """
)


def test_extract_blocks_finds_every_fence_with_its_line_and_language() -> None:
    blocks = rp.extract_blocks(PAGE)
    assert [(b.lang, b.line) for b in blocks] == [
        ("python", 3),
        ("pycon", 9),
        ("text", 16),
        ("bash", 20),
        ("python", 25),
        ("bash", 30),
    ]
    assert [b.runs for b in blocks] == [True, True, False, False, True, True]
    assert blocks[4].code == "y = x + 1\n"  # dedented out of the admonition


def test_blocks_share_one_namespace_in_order(tmp_path) -> None:
    run = rp.run_markdown(PAGE, "page.md", workdir=tmp_path)
    assert run.blocks == 4
    assert run.namespace["y"] == 3


def test_a_wrong_shown_output_fails_with_the_page_and_line() -> None:
    page = "```pycon\n>>> 1 + 1\n3\n```\n"
    with pytest.raises(rp.BlockError, match=r"page\.md:1") as info:
        rp.run_markdown(page, "page.md")
    assert "Expected:\n    3\nGot:\n    2" in str(info.value)


def test_a_wrong_exception_message_fails() -> None:
    page = (
        "```pycon\n>>> import policylab as pl\n>>> pl.discounted_return([1], 2.0)\n"
        "Traceback (most recent call last):\n...\n"
        "policylab.exceptions.InvalidArgumentError: gamma must be positive\n```\n"
    )
    with pytest.raises(rp.BlockError):
        rp.run_markdown(page, "page.md")


def test_a_raising_python_block_fails_with_the_page_and_line() -> None:
    page = "intro\n\n```python\nimport math\nmath.sqrt(-1)\n```\n"
    with pytest.raises(rp.BlockError, match=r"page\.md:3: the python block raised ValueError"):
        rp.run_markdown(page, "page.md")


def test_a_failing_marked_command_fails() -> None:
    page = "<!-- test: run -->\n```bash\npolicylab solve no-such-problem\n```\n"
    with pytest.raises(rp.BlockError, match=r"exited 2\n.*unknown problem 'no-such-problem'"):
        rp.run_markdown(page, "page.md")
    page = "<!-- test: run -->\n```bash\nfalse\n```\n"
    with pytest.raises(rp.BlockError, match="`false` exited 1"):
        rp.run_markdown(page, "page.md")


def test_figures_written_under_figures_are_returned(tmp_path) -> None:
    page = (
        "```python\nfrom pathlib import Path\nPath('figures/sub').mkdir(parents=True)\n"
        "Path('figures/sub/a.png').write_bytes(b'png')\nPath('other.txt').write_text('x')\n```\n"
    )
    run = rp.run_markdown(page, "page.md", workdir=tmp_path)
    assert run.figures == {"sub/a.png": b"png"}


def test_replacements_apply_and_a_stale_one_is_an_error() -> None:
    page = "```python\nn = 500_000\n```\n"
    assert rp.run_markdown(page, "p.md", replace={"500_000": "5"}).namespace["n"] == 5
    with pytest.raises(rp.BlockError, match="no code block contains"):
        rp.run_markdown(page, "p.md", replace={"400_000": "5"})


def test_docstring_roles_become_optional_references_to_where_objects_live() -> None:
    assert rp._canonical("policylab.FiniteMDP") == "policylab.mdp.finite.FiniteMDP"
    assert rp._canonical("policylab.no_such_name") == "policylab.no_such_name"

    class Page:
        class file:  # noqa: N801
            src_uri = "reference/api/planning.md"

    html = rp._cross_references(
        "see :class:<code>~policylab.FiniteMDP</code> and :func:<code>value_iteration</code>",
        Page,
    )
    assert html == (
        'see <autoref identifier="policylab.mdp.finite.FiniteMDP" optional>'
        "<code>FiniteMDP</code></autoref> and "
        '<autoref identifier="policylab.planning.control.value_iteration" optional>'
        "<code>value_iteration</code></autoref>"
    )
