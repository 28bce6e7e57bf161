"""The documentation site builds in strict mode, and every page's code runs in that build.

``mkdocs build --strict`` fails on a broken link, a missing page or API reference, a
docstring warning, or a code block that raises or shows the wrong output (the build's
hook runs every block; see ``docs/hooks/runpages.py``). This is what ``make docs`` runs.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest
from tests.docs._load import DOCS, ROOT, runpages

rp = runpages()


@pytest.fixture(scope="module")
def site(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, str]:
    out = tmp_path_factory.mktemp("site")
    env = {**os.environ, "NO_MKDOCS_2_WARNING": "1", "MPLBACKEND": "Agg"}
    proc = subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(out)],
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
        timeout=900,
        check=False,
    )
    log = proc.stdout + proc.stderr
    assert proc.returncode == 0, log[-6000:]
    return out, log


def _pages() -> list[Path]:
    return sorted(p for p in DOCS.rglob("*.md") if "hooks" not in p.parts)


def test_every_page_is_built(site: tuple[Path, str]) -> None:
    out, _ = site
    for page in _pages():
        rel = page.relative_to(DOCS).with_suffix("")
        html = out / (rel.parent if rel.name == "index" else rel) / "index.html"
        assert html.is_file(), f"{page} was not built ({html})"


def test_every_runnable_block_ran_in_the_build(site: tuple[Path, str]) -> None:
    _, log = site
    expected = sum(
        sum(b.runs for b in rp.extract_blocks(p.read_text(encoding="utf-8"))) for p in _pages()
    )
    m = re.search(r"ran (\d+) code blocks on (\d+) pages, (\d+) figures", log)
    assert m, log[-3000:]
    assert int(m.group(1)) == expected
    assert expected >= 90


def test_every_image_a_page_shows_was_drawn_by_its_code(site: tuple[Path, str]) -> None:
    out, _ = site
    shown = 0
    for page in _pages():
        for target in re.findall(r"!\[[^\]]*\]\(([^)]+)\)", page.read_text(encoding="utf-8")):
            src = (page.parent / target).relative_to(DOCS)
            assert (out / src).is_file(), f"{page.name} shows {target}, which was not drawn"
            assert not (DOCS / src).exists(), f"{src} is committed; figures are drawn in the build"
            assert (out / src).read_bytes()[:4] == b"\x89PNG"
            shown += 1
    assert shown >= 20


def test_equations_are_mathml_and_nothing_is_fetched_from_the_network(
    site: tuple[Path, str],
) -> None:
    out, _ = site
    page = (out / "tutorials" / "bellman" / "index.html").read_text(encoding="utf-8")
    assert '<math xmlns="http://www.w3.org/1998/Math/MathML" display="block">' in page
    assert 'class="arithmatex"' not in page  # every equation was converted
    for html in out.rglob("*.html"):
        text = html.read_text(encoding="utf-8")
        remote = re.findall(r'<(?:script|link|img)[^>]+(?:src|href)="(https?://[^"]+)"', text)
        assert not remote, f"{html.relative_to(out)} loads {remote}"


def test_docstring_cross_references_are_links_not_raw_roles(site: tuple[Path, str]) -> None:
    out, _ = site
    links = 0
    for html in (out / "reference").rglob("*.html"):
        text = html.read_text(encoding="utf-8")
        raw = re.findall(r":(?:class|func|meth|mod|attr|data|obj|exc):<code>", text)
        assert not raw, f"{html.relative_to(out)} shows raw roles {raw[:3]}"
        links += text.count('class="autorefs autorefs-internal"')
    assert links >= 50


def test_api_reference_documents_the_public_names(site: tuple[Path, str]) -> None:
    out, _ = site
    api = out / "reference" / "api"
    expect = {
        "mdp": ["policylab.mdp.FiniteMDP", "policylab.mdp.Policy"],
        "planning": ["policylab.planning.value_iteration", "policylab.planning.evaluate_policy"],
        "tabular": ["policylab.tabular.mc_prediction", "policylab.tabular.q_learning"],
        "deep": [
            "policylab.deep.PPO",
            "policylab.deep.DQN",
            "policylab.deep.SAC",
            "policylab.deep.TD3",
            "policylab.deep.WalkingReward",
        ],
        "games": [
            "policylab.games.solve_tic_tac_toe",
            "policylab.games.connect_four_solver",
            "policylab.games.UCT",
            "policylab.games.make_player",
            "policylab.games.arena.arena",
            "policylab.games.selfplay_td.TDPlayer",
        ],
        "exceptions": ["policylab.exceptions.InvalidMDPError"],
        "stats": [
            "policylab.stats.iqm",
            "policylab.stats.bootstrap_ci",
            "policylab.stats.summarize",
            "policylab.stats.read_sweep",
        ],
    }
    for page, names in expect.items():
        text = (api / page / "index.html").read_text(encoding="utf-8")
        for name in names:
            assert f'id="{name}"' in text, f"{name} missing from the {page} reference"
