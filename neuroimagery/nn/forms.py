"""The registry of a rule's forms: implementations of one learning rule on one kind of learner.

As a simulator's builder keeps several kernels for one rule (Nengo's ``Builder.register``), each
learner (:class:`~.connections.Connection`, :class:`~.local.LocalConnection`,
:class:`~.som.SOM`) finds the implementations of its rule here: ``@register(RuleType,
LearnerType)`` on a :class:`Form` subclass adds one. Every form gives the numbers of the plain rule
(step by step) up to float rounding; they differ in cost and in the inputs they accept. A form
owns everything about itself: when it applies, how it trains, and, when it forms the weights from
a few small factors, how it records them (``learner.learnt_factors``, a dict with the form's
``kind``), rebuilds the weights from them and bounds the rounding of that rebuild.

Lookup (:func:`forms_of`): the first class of the learner's MRO that has forms registered owns the
learner's forms (a :class:`~.local.LocalConnection` does not inherit the dense connection's);
among them, those registered for any class of the rule's MRO, by ``priority`` (lowest first),
then registration order. A form checks the exact rule it implements in :meth:`Form.why_not`.

Where the forms live (:data:`DEFINED_IN`, the registry's own list): :mod:`.connections` (the
plain step-by-step form), :mod:`.delta` (the delta rule and its binary-sequence and local index /
sparse / dense forms), :mod:`.hebbian_closed_form` (the outstar Hebbian closed forms),
:mod:`.local` (any rule restricted to local receptive fields), :mod:`.som_online`,
:mod:`.som_factored`, :mod:`.som_windowed`, :mod:`.som_repeated` (the online Kohonen rule). Each
registers its forms with ``@register`` where it defines them; the registry loads these modules,
in this order, before its first lookup, so which forms a learner has never depends on what else
was imported.
"""
from __future__ import annotations

import importlib
from typing import Any

# the modules that define forms, loaded in this order before the first lookup (the order of
# registration breaks ties of priority)
DEFINED_IN = ("connections", "hebbian_closed_form", "delta", "som_factored", "som_online", "som_repeated",
              "som_windowed", "local")
_loaded = False


def load() -> None:
    """Load every module of :data:`DEFINED_IN` (once): their ``@register`` s fill the registry."""
    global _loaded
    if not _loaded:
        _loaded = True
        for module in DEFINED_IN:
            importlib.import_module(f"{__package__}.{module}")


class Form:
    """One implementation of a rule on one kind of learner; subclasses override what they need.

    ``call`` is the learner's call, a namespace of its arguments (a connection's sequence:
    ``pre``, ``post``, ``batch``, ``kw``, ``progress``; a local connection's step: ``pre``,
    ``post``, ``kw``, ``out``; a SOM's fit: ``X``, ``order``, ``labels``, ``steps``, ``options``).
    """

    name: str = ""
    kind: str | None = None  # the kind of the factors it leaves in ``learner.learnt_factors`` (None: none)
    options: tuple[str, ...] = ()  # keyword arguments of the learner's call it reads (SOM.fit's ``parts``)
    priority: int = 5  # 'auto' tries lower first
    auto: bool = True  # whether 'auto' may pick it

    def why_not(self, learner, rule, call) -> str | None:
        """Why this form would not give the rule's numbers for this call (``None`` when it does)."""
        return None

    def suits(self, learner, rule, call) -> bool:
        """Whether 'auto' may pick it for this call (it must also apply)."""
        return self.auto

    def run(self, learner, rule, call) -> Any:
        """Train ``learner`` in place; a form with a ``kind`` returns its factors (a dict), which the
        learner keeps in ``learnt_factors``."""
        raise NotImplementedError

    # several learners in one loop (SOM's fit_together): None, or run_many(jobs) -> results
    run_many = None

    def rebuild(self, learner, factors: dict) -> None:
        """Form ``learner``'s trained weights in place from its initial weights and ``factors``."""
        raise ValueError(f"form {self.name!r} records no factors")

    def bound(self, factors: dict, w0, saved, rows):
        """The most ``rows`` of a rebuilt weight may differ from the ``saved`` rows when only the
        float rounding differs (``w0``: the initial weights' rows)."""
        raise ValueError(f"form {self.name!r} records no factors")

    def __repr__(self) -> str:
        return f"<form {self.name!r}>"


_FORMS: dict[type, dict[type, list[Form]]] = {}  # learner type -> rule type -> forms
_KINDS: dict[str, Form] = {}  # factor kind -> the form that records and rebuilds it


def register(rules: type | tuple[type, ...], learner: type):
    """Class decorator: register an instance of the :class:`Form` subclass as an implementation of
    each rule type of ``rules`` on ``learner`` (replacing a form of the same name there)."""
    rules = rules if isinstance(rules, tuple) else (rules,)

    def add(cls: type[Form]) -> type[Form]:
        form = cls()
        for rule in rules:
            table = _FORMS.setdefault(learner, {}).setdefault(rule, [])
            table[:] = [f for f in table if f.name != form.name] + [form]
        if form.kind is not None:
            _KINDS[form.kind] = form
        return cls

    return add


def _owner(learner) -> dict[type, list[Form]]:
    load()
    for klass in type(learner).__mro__:
        if klass in _FORMS:
            return _FORMS[klass]
    return {}


def forms_of(learner, rule=None) -> list[Form]:
    """The forms of ``learner`` (those of ``rule``'s type and its bases, or all when ``rule`` is
    None), in the order 'auto' tries them."""
    table = _owner(learner)
    keys = list(table) if rule is None else [k for k in type(rule).__mro__ if k in table]
    out: list[Form] = []
    for k in keys:
        out += [f for f in table[k] if f not in out]
    order = {id(f): i for i, f in enumerate(out)}
    return sorted(out, key=lambda f: (f.priority, order[id(f)]))


def names(learner) -> list[str]:
    """The names of every form registered for ``learner``'s type, sorted."""
    return sorted({f.name for f in forms_of(learner)})


def choose(learner, rule, call, method: str = "auto") -> Form | None:
    """The form for ``method``: with ``'auto'`` the first of :func:`forms_of` that suits and
    applies (None when none does); by name, that form, or a ``ValueError`` saying why it cannot
    train this call (an unknown name names the forms there are)."""
    if method == "auto":
        return next((f for f in forms_of(learner, rule) if f.suits(learner, rule, call)
                     and f.why_not(learner, rule, call) is None), None)
    form = next((f for f in forms_of(learner) if f.name == method), None)
    if form is None:
        raise ValueError(f"method must be 'auto' or one of {names(learner)}, got {method!r}")
    if form not in forms_of(learner, rule):
        raise ValueError(f"method={method!r} does not implement {type(rule).__name__}")
    extra = sorted(k for k, v in getattr(call, "options", {}).items() if v is not None and k not in form.options)
    if extra:
        raise ValueError(f"method={method!r} takes no {', '.join(extra)}")
    why = form.why_not(learner, rule, call)
    if why:
        raise ValueError(f"method={method!r} {why}")
    return form


def factor_form(factors: dict) -> Form:
    """The form that recorded ``factors`` (by their ``kind``)."""
    kind = factors.get("kind") if isinstance(factors, dict) else None
    load()
    if kind not in _KINDS:
        raise ValueError(f"unknown factor kind {kind!r} (known: {sorted(_KINDS)})")
    return _KINDS[kind]


def rebuild(learner, factors: dict) -> None:
    """Form ``learner``'s trained weights again from its initial weights and the ``factors`` a
    form recorded, by that form's own products."""
    factor_form(factors).rebuild(learner, factors)


def bound(factors: dict, w0, saved, rows):
    """:meth:`Form.bound` of the form that recorded ``factors``."""
    return factor_form(factors).bound(factors, w0, saved, rows)
