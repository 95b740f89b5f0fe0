"""Device families, a module each (its [scan] keys, check and pattern builder), and the registry the core and the UI read (registry.py: FAMILIES)."""

from .registry import FAMILIES, Family, family_of

__all__ = ["FAMILIES", "Family", "family_of"]
