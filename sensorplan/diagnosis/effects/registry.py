"""The effects by name: one registry that maps each name to its class.

The library's effects are registered by the package (``effects/__init__``)
in the order in which they are screened; a new effect is one class
registered here with :func:`register_effect` (docs/api.md, "Adding an
effect"), after which ``diagnose`` offers it by default.

Owns: the registry.  May import: the effect protocol and the foundations.
"""

from types import MappingProxyType

from ..._errors import ConfigError
from .base import Effect

__all__ = ["EFFECTS", "effect_names", "make_effect", "register_effect", "unregister_effect"]

_REGISTRY: dict = {}
EFFECTS = MappingProxyType(_REGISTRY)  # name -> class, in registration order (read-only view)


def register_effect(cls):
    """Add the effect class ``cls`` to the candidates of ``diagnose`` under ``cls.name``; returns ``cls``.

    Usable as a class decorator.  ``cls`` must subclass
    :class:`~.base.StructuralEffect` or :class:`~.base.OutputEffect` and
    construct without arguments; a name may be registered once.
    """
    if not (isinstance(cls, type) and issubclass(cls, Effect)) or not isinstance(cls.name, str) or not cls.name:
        raise ConfigError(f"register_effect needs a subclass of StructuralEffect or OutputEffect with a 'name'. "
                          f"Got {cls!r} instead.")
    if _REGISTRY.get(cls.name, cls) is not cls:
        raise ConfigError(f"An effect named {cls.name!r} is registered already ({_REGISTRY[cls.name].__name__}); "
                          "choose another name or unregister_effect it first.")
    _REGISTRY[cls.name] = cls
    return cls


def unregister_effect(name):
    """Remove the effect ``name`` from the registry (a test's toy effect, for instance)."""
    _REGISTRY.pop(name, None)


def effect_names():
    """The registered effects' names, in the order ``diagnose`` screens them."""
    return tuple(_REGISTRY)


def make_effect(name):
    """A new effect object of the registered class ``name``."""
    try:
        cls = _REGISTRY[name]
    except KeyError:
        raise ConfigError(f"Unknown effect {name!r}; choose from {', '.join(_REGISTRY)}.") from None
    return cls()
