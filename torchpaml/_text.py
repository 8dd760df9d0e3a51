r"""Text that a model file carries and that exporters print into C, Python and LaTeX: checked when it is read, and
made inert when it is printed.

A string read from a model file (a physics' argument or attribute, a display name, a term) is *plain text*: at
most :data:`MAX_TEXT` characters of letters, digits, space and ``_ . , : + - * / ( ) [ ] ^ = < >``, and neither
``/*`` nor ``*/`` (which open and close a C comment). :func:`check_plain_text` refuses anything else in one line at
load, so no quote, backslash, newline, ``#`` or ``;`` can reach generated code. :func:`inert_comment` is the
printers' own guard: what it returns stays inside a C comment or a Python docstring whatever it was given.
"""

from __future__ import annotations

import re

from torchpaml._errors import ConfigurationError

__all__ = ["MAX_TEXT", "check_plain_text", "inert_comment"]

#: The longest plain text a model file may carry in one string.
MAX_TEXT = 2000
_PLAIN = re.compile(r"[A-Za-z0-9 _.,:+\-*/()\[\]^=<>]*")


def check_plain_text(text: str, where: str) -> str:
    """``text`` itself where it is plain text (module docstring); else :class:`~torchpaml.ConfigurationError` naming
    ``where`` it was found (e.g. "the physics' attribute 'name'")."""
    if len(text) > MAX_TEXT or not _PLAIN.fullmatch(text) or "/*" in text or "*/" in text:
        raise ConfigurationError(f"{where} is {text[:60]!r}{'...' if len(text) > 60 else ''}, which is not plain "
                                 "text: a model file's strings hold letters, digits, space and _ . , : + - * / ( ) [ ] "
                                 "^ = < > (no '/*' or '*/', no quotes, backslashes or line breaks); the file was not "
                                 "written by torchpaml.save_model or was changed")
    return text


def inert_comment(text: str) -> str:
    """``text`` made safe inside a C comment and a Python docstring: characters outside plain text become ``?`` and
    ``*/`` and ``/*`` are split, so that neither the comment nor the docstring can end early."""
    kept = "".join(c if _PLAIN.fullmatch(c) else "?" for c in text)
    while "*/" in kept or "/*" in kept:
        kept = kept.replace("*/", "* /").replace("/*", "/ *")
    return kept
