"""A griffe extension for the API reference: readable cross-references and the method beside each function.

- The library's docstrings cross-reference with Sphinx roles (``:func:`~torchpaml.fit_physics```), which
  mkdocstrings would print verbatim; each role becomes the object's name as inline code (the last
  component with ``~``, Sphinx's convention, else the path as written).
- Functions and classes describe their method once, in their (private) module's docstring, and say
  "(module docstring)". The reference shows the public objects, not the modules, so the module
  docstring is appended, under "The method", to the first function of the module that refers to it
  (else the first class); the module's other objects point to that one.
"""

from __future__ import annotations

import re
from typing import Any

import griffe

ROLE = re.compile(r":(?:func|class|meth|mod|data|attr|obj|exc):`(~?)([^`]+)`")
MENTION = re.compile(r"\((?:see )?(?:the )?module docstring(?P<rest>[^)]*)\)")


def _plain(match: re.Match) -> str:
    tilde, target = match.groups()
    return f"`{target.rsplit('.', 1)[-1] if tilde else target}`"


def _public_objects(parent: griffe.Object) -> list[griffe.Object]:
    """The public objects defined in ``parent`` with a docstring, classes' members after their class."""
    found = []
    for member in parent.members.values():
        if member.is_alias or member.name.startswith("_"):
            continue
        if member.docstring is not None:
            found.append(member)
        if member.is_class:
            found += _public_objects(member)
    return found


class SphinxRolesToCode(griffe.Extension):
    """Rewrite Sphinx roles and attach each module's method to its first public function (module docstring)."""

    def on_instance(self, *, obj: griffe.Object, **kwargs: Any) -> None:
        if obj.docstring is not None:
            obj.docstring.value = ROLE.sub(_plain, obj.docstring.value)

    def on_module_members(self, *, mod: griffe.Module, **kwargs: Any) -> None:
        if mod.docstring is None:
            return
        members = [m for m in _public_objects(mod) if MENTION.search(m.docstring.value)]
        if not members:
            return
        primary = next((m for m in members if m.is_function and m.parent is mod), members[0])
        method = ROLE.sub(_plain, mod.docstring.value)
        for member in members:
            if member is primary:
                text = MENTION.sub(lambda m: f"(the method, below{m['rest']})", member.docstring.value)
                member.docstring.value = f"{text}\n\n**The method.**\n\n{method}"
            else:
                member.docstring.value = MENTION.sub(lambda m: f"(see `{primary.name}`{m['rest']})",
                                                     member.docstring.value)
