"""A case with holes: the parts validation could build, placeholders for the rest.

A coupler's ``check_case(case)`` is asked about a case even when other
parts of the case are invalid, so that its objections are reported in the
same pass as every other problem.  The parts that could not be built are
:class:`Unbuilt` placeholders: reading one raises :class:`NotBuilt`, and the
validator then keeps that coupler's objections for a pass where the parts
it reads are valid.  A coupler is thus asked whenever the parts it inspects
could be built, whichever they are.
"""

from __future__ import annotations

from typing import Any, NoReturn


class NotBuilt(Exception):
    """A coupler read a part of the case that validation could not build."""


class Unbuilt:
    """A part of a case that could not be built; reading it in any way raises :class:`NotBuilt`.

    Only identity survives (``part is None`` is False: the part was given,
    it is just invalid).

    >>> part = Unbuilt("layers")
    >>> part is None
    False
    >>> len(part)
    Traceback (most recent call last):
    ...
    multilayer.case.partial.NotBuilt: layers
    >>> part.anything
    Traceback (most recent call last):
    ...
    multilayer.case.partial.NotBuilt: layers
    """

    __slots__ = ("where",)

    def __init__(self, where: str):
        object.__setattr__(self, "where", where)

    def _refuse(self, *args: Any, **kwargs: Any) -> NoReturn:
        raise NotBuilt(self.where)

    def __getattr__(self, name: str) -> NoReturn:
        raise NotBuilt(self.where)

    __getitem__ = __iter__ = __len__ = __bool__ = __contains__ = __call__ = _refuse
    __float__ = __int__ = __index__ = __str__ = __format__ = _refuse

    def __repr__(self) -> str:
        return f"<{self.where}: not built>"
