"""A library of candidate effects: the effects a model may be built from and a diagnosis tries.

Like PySINDy's feature libraries, libraries are values that combine with ``+``: the built-in
:data:`~surrogate.effects.LIBRARY` plus the effects of a user's file,
``LIBRARY + load_effects_file("my_effects.py")``. Nothing global changes when a file is loaded;
whoever needs the user's effects is handed the combined library.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator, Mapping

from ..core.errors import InputError
from .base import CATEGORIES, KINDS, Effect


class EffectLibrary(Mapping[str, type[Effect]]):
    """Effect classes by name; immutable, combined with ``+``.

    Raises
    ------
    InputError
        For an effect without a name, a known kind or a known category, or two different effects of one name.
    """

    def __init__(self, effects: Iterable[type[Effect]] = ()):
        self._effects: dict[str, type[Effect]] = {}
        for cls in effects:
            if not cls.name or cls.kind not in KINDS:
                raise InputError(f"{cls.__name__}: an effect needs a name and a kind in "
                                 f"{', '.join(KINDS)}")
            if cls.category not in CATEGORIES:
                raise InputError(f"effect {cls.name!r}: its category {cls.category!r} is not one "
                                 f"of {', '.join(CATEGORIES)}")
            existing = self._effects.get(cls.name)
            if existing is not None and existing is not cls:
                raise InputError(f"an effect named {cls.name!r} exists already; choose another "
                                 "name")
            self._effects[cls.name] = cls

    def __getitem__(self, name: str) -> type[Effect]:
        return self._effects[name]

    def __iter__(self) -> Iterator[str]:
        return iter(self._effects)

    def __len__(self) -> int:
        return len(self._effects)

    def __add__(self, other: "EffectLibrary") -> "EffectLibrary":
        return EffectLibrary([*self._effects.values(), *other.values()])

    def __repr__(self) -> str:
        return f"EffectLibrary({', '.join(self._effects)})"

    def effect(self, name: str) -> type[Effect]:
        """The effect called ``name``, or an InputError listing the known ones."""
        try:
            return self._effects[name]
        except (KeyError, TypeError):
            raise InputError(f"unknown effect {name!r}; known effects: "
                             f"{', '.join(self._effects)} (custom ones need --effects-file)"
                             ) from None

    def without(self, names: Iterable[str]) -> "EffectLibrary":
        """The library less the named effects."""
        names = set(names)
        return EffectLibrary(cls for name, cls in self._effects.items() if name not in names)
