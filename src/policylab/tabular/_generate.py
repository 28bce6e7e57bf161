"""Write the TD learners' public functions into ``td.py`` from its ``TD_ENTRIES``.

Run ``python -m policylab.tabular._generate`` after changing an entry: each learner's
signature and Google docstring (visible to editors and ``help()``) come from its entry
and the shared options, so that the function, the registry and ``policylab learn``
cannot drift apart. ``python -m policylab.tabular._generate --check`` exits 1 if the
file is out of date (the test suite checks the same).
"""

from __future__ import annotations

import sys
import textwrap
from pathlib import Path

START, END = "# <generated learners>\n", "# </generated learners>\n"

_OPTIONS = "The options every learner shares, :class:`~policylab.tabular.LearnOptions`."
_PROBLEM = "A FiniteMDP (compiled) or a Gymnasium env with Discrete observations."
_POLICY = "A :class:`~policylab.Policy` or an (S, A) array (default: equiprobable)."
_RETURNS_CONTROL = "A :class:`LearnResult` (the error is against q* where the model is known)."
_RETURNS_PREDICTION = "A :class:`LearnResult` (the error of V is against v_pi, as above)."


def _arg_doc(name: str, doc: str) -> list[str]:
    lines = textwrap.wrap(f"{name}: {doc}", width=88)
    return [" " * 8 + lines[0], *(" " * 12 + x for x in lines[1:])]


def render_learner(entry: object) -> str:
    """The source of one learner's public function."""
    from policylab.tabular.td import _ALPHA, _EPSILON, _INIT, TDEntry

    assert isinstance(entry, TDEntry)
    episodes = ("episodes", "int", str(entry.default_episodes), "Number of episodes.")
    shared_opts = (_ALPHA, *((_EPSILON,) if entry.control else ()), _INIT)
    params = [
        *((o.param, o.annotation, o.value, o.doc or o.help) for o in entry.own),
        episodes,
        *((o.param, o.annotation, o.value, o.doc or o.help) for o in shared_opts),
    ]
    sig = ["    problem: FiniteMDP | Any,"]
    if not entry.control:
        sig.append("    policy: Policy | Any = None,")
    sig.append("    *,")
    sig += [f"    {name}: {ann} = {default}," for name, ann, default, _ in params]
    sig.append("    **options: Unpack[LearnOptions],")
    doc = ['    """' + entry.title, ""]
    doc += ["    " + line for line in entry.equation.splitlines()]
    doc += ["", "    Args:", *_arg_doc("problem", _PROBLEM)]
    if not entry.control:
        doc += _arg_doc("policy", _POLICY)
    for name, _, _, text in params:
        doc += _arg_doc(name, text)
    doc += _arg_doc("**options", _OPTIONS)
    returns = _RETURNS_CONTROL if entry.control else _RETURNS_PREDICTION
    doc += ["", "    Returns:", *(" " * 8 + x for x in textwrap.wrap(returns, width=88))]
    doc.append('    """')
    call = [f'    return learn_entry("{entry.name}", locals())']
    return "\n".join([f"def {entry.function}(", *sig, ") -> LearnResult:", *doc, *call]) + "\n"


def render() -> str:
    """The whole generated block (every learner of ``TD_ENTRIES``)."""
    from policylab.tabular.td import TD_ENTRIES

    return "\n\n".join(render_learner(e) for e in TD_ENTRIES)


def target() -> Path:
    """The file the learners are written into."""
    return Path(__file__).with_name("td.py")


def updated(text: str) -> str:
    """``text`` (td.py's source) with the generated block replaced by :func:`render`."""
    a = text.index(START) + len(START)
    b = text.index(END)
    return text[:a] + "\n\n" + render() + "\n\n" + text[b:]


def main(argv: list[str] | None = None) -> int:
    """Rewrite td.py's generated block (``--check``: only report whether it is current)."""
    args = sys.argv[1:] if argv is None else argv
    path = target()
    text = path.read_text()
    new = updated(text)
    if "--check" in args:
        if new != text:
            print(f"{path} is out of date: run python -m policylab.tabular._generate")
            return 1
        return 0
    if new != text:
        path.write_text(new)
    return 0


if __name__ == "__main__":
    sys.exit(main())
