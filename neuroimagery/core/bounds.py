"""Declared bounds of configuration fields: one mechanism for every range check of a setting.

A field states its bounds where it is declared, in the dataclass field's metadata::

    iterations: int = bounded(2000, ge=1)  # online training steps
    method: str = bounded("windowed", choices=("windowed", "factored", "online"))
    ages: list[int] = bounded(factory=lambda: [14, 16], ge=0, each=True)

:func:`check_declared` reads them generically: a group's ``__post_init__`` calls it on itself
(so a dataclass built in Python is checked too), and :func:`neuroimagery.validation.check_run`
walks the whole configuration with it before any work, naming each key by its full path
(``experiment.som.iterations must be >= 1, got 0``). A new parameter gets its check by declaring
its bounds; nothing else is written for it.

What bounds cannot say (a value against another field, an angle that must divide 180) is a
:class:`Rule` the group declares once, in its ``RULES`` class attribute; :func:`check_declared`
checks the rules after the bounds, so a group holds no hand-written range check::

    RULES = (Rule("hp1_ages", lambda c: len(c.hp1_ages) == len(c.hp1_levels),
                  "must give one age per entry of hp1_levels"),)
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import MISSING, dataclass, field
from typing import Any, Callable, Optional, Sequence

from .errors import UserInputError


def _num(x) -> str:
    """A bound as written: an integer in full (``2 ** 63`` is 9223372036854775808), else ``%g``."""
    return str(x) if isinstance(x, int) and not isinstance(x, bool) else f"{x:g}"


@dataclass(frozen=True)
class Bounds:
    """What a field's value may be. ``None`` bounds are not checked; ``each``: the value is a list
    and every item is checked; ``null``: ``None`` is accepted (an optional setting)."""

    ge: Optional[float] = None
    gt: Optional[float] = None
    le: Optional[float] = None
    lt: Optional[float] = None
    choices: Optional[tuple] = None
    each: bool = False
    null: bool = True
    nonempty: bool = False
    why: str = ""  # appended to the refusal: what the bound means

    def text(self) -> str:
        """The bound in words: ``>= 1``, ``in (0, 255]``, ``one of 'a', 'b'``."""
        if self.choices is not None:
            return "one of " + ", ".join(map(repr, self.choices))
        lo = f"[{_num(self.ge)}" if self.ge is not None else (f"({_num(self.gt)}" if self.gt is not None else None)
        hi = f"{_num(self.le)}]" if self.le is not None else (f"{_num(self.lt)})" if self.lt is not None else None)
        if lo and hi:
            return f"in {lo}, {hi}"
        if lo:
            return (">= " if lo[0] == "[" else "> ") + lo[1:]
        if hi:
            return ("<= " if hi[-1] == "]" else "< ") + hi[:-1]
        return "set"

    def fails(self, value: Any) -> bool:
        """Whether the single value ``value`` breaks these bounds."""
        if value is None:
            return not self.null
        if self.choices is not None:
            return value not in self.choices
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            return any(b is not None for b in (self.ge, self.gt, self.le, self.lt))
        if isinstance(value, float) and math.isnan(value):
            return True
        return ((self.ge is not None and not value >= self.ge) or (self.gt is not None and not value > self.gt)
                or (self.le is not None and not value <= self.le) or (self.lt is not None and not value < self.lt))

    def check(self, key: str, value: Any) -> None:
        """Raise :class:`UserInputError` naming ``key`` if ``value`` breaks these bounds."""
        why = f" ({self.why})" if self.why else ""
        if self.each:
            if value is None:
                if not self.null:
                    raise UserInputError(f"{key} must be a list, got None")
                return
            items = list(value)
            if self.nonempty and not items:
                raise UserInputError(f"{key} must not be empty{why}")
            for i, v in enumerate(items):
                if self.fails(v):
                    raise UserInputError(f"{key}[{i}] must be {self.text()}{why}, got {v!r}")
            return
        if self.fails(value):
            raise UserInputError(f"{key} must be {self.text()}{why}, got {value!r}")


def bounded(default: Any = MISSING, *, factory: Optional[Callable[[], Any]] = None, ge=None, gt=None, le=None,
            lt=None, choices: Optional[Sequence] = None, each: bool = False, null: bool = True,
            nonempty: bool = False, why: str = "") -> Any:
    """A dataclass field with its bounds declared (see the module docstring)."""
    meta = {"bounds": Bounds(ge=ge, gt=gt, le=le, lt=lt, choices=tuple(choices) if choices is not None else None,
                             each=each, null=null, nonempty=nonempty, why=why)}
    if factory is not None:
        return field(default_factory=factory, metadata=meta)
    return field(default=default, metadata=meta)


@dataclass(frozen=True)
class Rule:
    """A declared check that bounds cannot express: ``holds(group)`` is true of a valid group; a
    refusal reads ``<prefix><key> <must>, got <value>`` (``show=False``: without the value)."""

    key: str
    holds: Callable[[Any], bool]
    must: str
    show: bool = True

    def check(self, obj: Any, prefix: str) -> None:
        """Raise :class:`UserInputError` naming the key if the rule does not hold of ``obj``."""
        if not self.holds(obj):
            value = obj
            for part in self.key.split("."):
                value = getattr(value, part, None)
            got = f", got {value!r}" if self.show else ""
            raise UserInputError(f"{prefix}{self.key} {self.must}{got}")


def bounds_of(cls_or_obj) -> dict[str, Bounds]:
    """``{field name: Bounds}`` of the fields of a dataclass that declare bounds."""
    return {f.name: f.metadata["bounds"] for f in dataclasses.fields(cls_or_obj) if "bounds" in f.metadata}


def check_declared(obj: Any, prefix: str = "", recursive: bool = True) -> None:
    """Check every declared bound of the dataclass ``obj`` (and, ``recursive``, of the dataclasses
    it holds), then its declared :class:`Rule` s (``RULES``); a refusal names the key as
    ``prefix + field`` (``prefix``: ``"experiment.fm."``)."""
    if not dataclasses.is_dataclass(obj) or isinstance(obj, type):
        return
    for f in dataclasses.fields(obj):
        value = getattr(obj, f.name, None)
        b = f.metadata.get("bounds")
        if b is not None:
            b.check(f"{prefix}{f.name}", value)
        if recursive and dataclasses.is_dataclass(value) and not isinstance(value, type):
            check_declared(value, f"{prefix}{f.name}.", recursive=True)
    for rule in getattr(type(obj), "RULES", ()):
        rule.check(obj, prefix)
