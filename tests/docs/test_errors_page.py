"""The error reference covers every error and warning type policylab defines."""

from __future__ import annotations

import inspect
import re

from tests.docs._load import DOCS

import policylab.exceptions as exc


def test_every_error_type_has_a_section_with_a_real_example() -> None:
    text = (DOCS / "reference" / "errors.md").read_text(encoding="utf-8")
    types = [
        name
        for name, obj in vars(exc).items()
        if inspect.isclass(obj)
        and obj.__module__ == exc.__name__
        and (issubclass(obj, exc.PolicylabError) or issubclass(obj, Warning))
        and obj is not exc.PolicylabError
    ]
    assert len(types) >= 9
    sections = dict(re.findall(r"^## (\w+)\n(.*?)(?=^## |\Z)", text, flags=re.S | re.M))
    for name in types:
        assert name in sections, f"errors.md has no section on {name}"
        body = sections[name]
        assert "```pycon" in body, f"the {name} section has no example"
        if name != "NotConvergedWarning":
            assert f"policylab.exceptions.{name}: " in body, f"{name} is never shown raised"
