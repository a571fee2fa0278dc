"""The bundled material library (``pliant/data/materials.toml``): typical handbook
values, each with its source, looked up by name."""

from __future__ import annotations

import tomllib
from functools import cache
from importlib import resources

from pliant.core.part import Material
from pliant.errors import InputError

PROVENANCE = ("measured", "identified", "handbook", "correlation")


@cache
def library() -> dict[str, dict]:
    """Every entry of the library, by name: youngs_modulus [Pa], density [kg/m^3],
    poisson_ratio, description, source and provenance (one of ``PROVENANCE``)."""
    text = resources.files("pliant.data").joinpath("materials.toml").read_text("utf-8")
    entries = tomllib.loads(text)
    for name, entry in entries.items():
        if entry.get("provenance") not in PROVENANCE or not entry.get("source"):
            raise InputError(f"materials.toml: [{name}]", "every entry states its source "
                             f"and its provenance ({', '.join(PROVENANCE)})")
    return entries


def material(name: str) -> Material:
    """The library's material called ``name`` (case-insensitive)."""
    entries = {key.lower(): (key, value) for key, value in library().items()}
    found = entries.get(name.lower())
    if found is None:
        raise InputError("material", f"no material {name!r} in the library; known: "
                         f"{', '.join(sorted(library()))} (or give a [part.material] table "
                         "with youngs_modulus and density)")
    key, entry = found
    return Material(youngs_modulus=entry["youngs_modulus"], density=entry["density"],
                    poisson_ratio=entry.get("poisson_ratio", 0.5), name=key)
