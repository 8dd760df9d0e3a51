"""The arguments a module was built with, kept so that a model file can build it again without pickling it.

A class that derives from :class:`Rebuildable` (every physics, effect and residual does) records, on each
instance, the class and the arguments of the outermost ``__init__`` that built it: ``Tank(area=2.0)`` keeps
``(Tank, (), {"area": 2.0})``. A model file stores them by name (``module.Class``) and calls the class again with
them, as a config's ``class_path``/``init_args`` does; a user's class records its arguments with no code of its own.
"""

from __future__ import annotations

import functools
from typing import Any

__all__ = ["Rebuildable", "built_with"]


class Rebuildable:
    """Mixin: each instance keeps the class and the arguments it was built with (:func:`built_with`)."""

    def __init_subclass__(cls, **kwargs):
        super().__init_subclass__(**kwargs)
        init = cls.__dict__.get("__init__")
        if init is None:  # torch's parametrisation subclasses, and classes that inherit their __init__
            return

        @functools.wraps(init)
        def recording(self, *args, **kw):
            if "_built_with" not in self.__dict__:  # the outermost __init__ (a subclass's) records; super()'s do not
                self.__dict__["_built_with"] = (type(self), args, kw)
            init(self, *args, **kw)

        cls.__init__ = recording


def built_with(module: Rebuildable) -> tuple[type, tuple, dict[str, Any]]:
    """``(class, args, kwargs)`` that built ``module`` (a :class:`Rebuildable`)."""
    return module.__dict__["_built_with"]
