"""Read an evaluation rules table (TOML, SI units) into ``pliant.core.rules.Rules``.

The bundled table is ``pliant/data/rules.toml``; a user's own file replaces it whole.
Every number must be positive and every row must name its unit, source and provenance,
so that a verdict can always say which rule it applied and where the rule comes from.
"""

from __future__ import annotations

from functools import cache
from importlib import resources
from pathlib import Path
from typing import Literal

from pydantic import BaseModel, ConfigDict, Field, PositiveFloat, ValidationError, model_validator

from pliant.core.rules import (
    Body,
    Capacity,
    HandEnvelope,
    Packaging,
    PartKind,
    PostureZones,
    Rules,
    Sourced,
)
from pliant.errors import FileFormatError
from pliant.io.tomlfile import field_path, read_text, read_toml

UNITS = {"axial": "N", "lateral": "N", "grip": "N", "force": "N", "twist": "N m",
         "bending": "N m"}


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class _SourcedModel(_Strict):
    source: str = Field(min_length=1)
    provenance: str = Field(min_length=1)


class ZonesModel(_SourcedModel):
    green: float = Field(gt=0, lt=1)
    yellow: float = Field(gt=0, le=1)

    @model_validator(mode="after")
    def _ordered(self) -> ZonesModel:
        if not self.green < self.yellow:
            raise ValueError("green must be below yellow")
        return self


class HandModel(_Strict):
    friction: float = Field(gt=0, le=5)
    friction_source: str = Field(min_length=1)
    friction_provenance: str = Field(min_length=1)


class CapacityModel(_SourcedModel):
    id: str = Field(min_length=1)
    title: str = Field(min_length=1)
    demand: Literal["axial", "lateral", "grip", "force", "twist", "bending"]
    unit: Literal["N", "N m"]
    capacity: float | None = Field(None, gt=0)
    green: float | None = Field(None, gt=0)
    yellow: float | None = Field(None, gt=0)
    unscored_below: float = Field(0.0, ge=0)
    repetitive_yellow: float | None = Field(None, gt=0)

    @model_validator(mode="after")
    def _limits(self) -> CapacityModel:
        if self.unit != UNITS[self.demand]:
            raise ValueError(f"a {self.demand} demand is in {UNITS[self.demand]}, "
                             f"not {self.unit}")
        if self.capacity is None and (self.green is None or self.yellow is None):
            raise ValueError("give the capacity, or both green and yellow limits")
        if self.green is not None and self.yellow is not None and self.green >= self.yellow:
            raise ValueError("green must be below yellow")
        return self

    def _limit(self, given: float | None, fraction: float) -> float:
        """A zone's onset: as given, or that fraction of the capacity."""
        if given is not None:
            return given
        assert self.capacity is not None  # _limits asks for one or the other
        return fraction * self.capacity

    def build(self, zones: ZonesModel) -> Capacity:
        green = self._limit(self.green, zones.green)
        yellow = self._limit(self.yellow, zones.yellow)
        return Capacity(self.id.lower(), self.title, self.demand, self.unit, green, yellow,
                        self.capacity, self.unscored_below, self.repetitive_yellow,
                        Sourced(self.source, self.provenance))


class ToolModel(_SourcedModel):
    green: float = Field(gt=0, lt=1)
    yellow: float = Field(gt=0, le=1)


class KindModel(_Strict):
    id: str = Field(min_length=1)
    bend_radius_to: Literal["inside", "centreline"]
    fallback_od: float | None = Field(None, gt=0)
    fallback_source: str = ""
    thin_walled: bool
    hose: bool
    source: str = Field(min_length=1)

    @model_validator(mode="after")
    def _fallback_sourced(self) -> KindModel:
        if self.fallback_od is not None and not self.fallback_source:
            raise ValueError("a fallback_od needs its fallback_source")
        return self

    def build(self) -> PartKind:
        return PartKind(self.id.lower(), self.bend_radius_to, self.fallback_od,
                        self.fallback_source, self.thin_walled, self.hose,
                        Sourced(self.source, "fallback" if self.fallback_od else "standard"))


class BendModel(_Strict):
    margin: float = Field(ge=1)
    margin_source: str = Field(min_length=1)
    fitting_straight: float = Field(gt=0)
    fitting_tight: float = Field(gt=1)
    fitting_source: str = Field(min_length=1)


class KinkModel(_Strict):
    yellow: float = Field(gt=0, lt=1)
    red: float = Field(gt=0, lt=1)
    min_ratio: float = Field(gt=0)
    source: str = Field(min_length=1)


class TwistModel(_Strict):
    yellow: float = Field(gt=0, description="degrees")
    red: float = Field(gt=0, description="degrees")
    source: str = Field(min_length=1)


class StretchModel(_Strict):
    margin: float = Field(ge=1, description="yellow above the allowed strain / margin")
    source: str = Field(min_length=1)


class PackagingModel(_Strict):
    hot_unshielded: float = Field(gt=0, description="[m] from a hot obstacle, unshielded")
    hot_shielded: float = Field(gt=0, description="[m] from a hot obstacle behind a shield")
    hot_source: str = Field(min_length=1)
    moving: float = Field(gt=0, description="[m] from a moving obstacle")
    moving_source: str = Field(min_length=1)
    edge_source: str = Field(min_length=1)

    def build(self) -> Packaging:
        return Packaging(self.hot_unshielded, self.hot_shielded,
                         Sourced(self.hot_source, "guideline"), self.moving,
                         Sourced(self.moving_source, "guideline"),
                         Sourced(self.edge_source, "guideline"))


class AccessModel(_Strict):
    breadth: float = Field(gt=0, description="[m] across the knuckles")
    breadth_source: str = Field(min_length=1)
    thickness: float = Field(gt=0, description="[m] at the metacarpals")
    thickness_source: str = Field(min_length=1)
    pinch_breadth: float = Field(gt=0, description="[m] two fingertips side by side")
    pinch_thickness: float = Field(gt=0, description="[m] a finger's")
    pinch_source: str = Field(min_length=1)
    palm: float = Field(gt=0, description="[m] from the part's axis to the wrist")
    forearm: float = Field(gt=0, description="[m] from the wrist to the elbow")
    wrist: tuple[PositiveFloat, PositiveFloat] = Field(description="[m] (breadth, thickness)")
    elbow: tuple[PositiveFloat, PositiveFloat] = Field(description="[m] (breadth, thickness)")
    arm_source: str = Field(min_length=1)
    glove: float = Field(ge=0, description="[m] a glove's thickness")
    allowance: float = Field(ge=0, description="[m] yellow within it")
    allowance_source: str = Field(min_length=1)
    directions: int = Field(ge=4, le=360)
    tilts: list[float] = Field(default_factory=lambda: [0.0], min_length=1,
                               description="[deg] the forearm tilted along the part")
    upper_arm: float = Field(0.06, gt=0, description="[m] the upper arm's radius, shoulder "
                             "to elbow, with clothing")
    provenance: str = Field(min_length=1)

    @model_validator(mode="after")
    def _tilts(self) -> AccessModel:
        if not all(-80.0 <= t <= 80.0 for t in self.tilts):
            raise ValueError("tilts: each within -80 to 80 degrees of square to the part")
        return self

    def build(self) -> HandEnvelope:
        source = "; ".join([f"hand breadth {self.breadth * 1e3:g} mm: {self.breadth_source}",
                            f"hand thickness {self.thickness * 1e3:g} mm: "
                            f"{self.thickness_source}",
                            f"pinch: {self.pinch_source}", f"forearm: {self.arm_source}",
                            f"allowance {self.allowance * 1e3:g} mm: {self.allowance_source}"])
        return HandEnvelope(self.breadth, self.thickness, self.pinch_breadth,
                            self.pinch_thickness, self.palm, self.forearm,
                            (self.wrist[0], self.wrist[1]), (self.elbow[0], self.elbow[1]),
                            self.glove,
                            self.allowance, self.directions, Sourced(source, self.provenance),
                            tuple(self.tilts), self.upper_arm)


Pair = tuple[PositiveFloat, PositiveFloat]


class BodyModel(_Strict):
    population: str = Field(min_length=1)
    stature_men: Pair = Field(description="[m] (mean, SD)")
    stature_women: Pair = Field(description="[m] (mean, SD)")
    shoulder_grip_men: Pair = Field(description="[m] (mean, SD)")
    shoulder_grip_women: Pair = Field(description="[m] (mean, SD)")
    source: str = Field(min_length=1)
    shoulder_height: float = Field(gt=0, lt=1, description="of stature")
    hip_height: float = Field(gt=0, lt=1, description="of stature")
    knee_height: float = Field(gt=0, lt=1, description="of stature")
    shoulder_breadth: float = Field(gt=0, lt=1, description="of stature")
    upper_arm: float = Field(gt=0, lt=1, description="of stature")
    proportions_source: str = Field(min_length=1)

    @model_validator(mode="after")
    def _ordered(self) -> BodyModel:
        if not self.knee_height < self.hip_height < self.shoulder_height:
            raise ValueError("knee_height < hip_height < shoulder_height (of stature)")
        return self

    def build(self) -> Body:
        return Body(self.population,
                    {"men": self.stature_men, "women": self.stature_women},
                    {"men": self.shoulder_grip_men, "women": self.shoulder_grip_women},
                    self.shoulder_height, self.hip_height, self.knee_height,
                    self.shoulder_breadth, self.upper_arm,
                    Sourced(f"{self.source}; {self.proportions_source}", "published table"))


class PostureModel(_Strict):
    upper_arm: Pair = Field(description="[deg] yellow above, red above")
    trunk: Pair = Field(description="[deg] yellow above, red above")
    source: str = Field(min_length=1)
    provenance: str = Field(min_length=1)

    @model_validator(mode="after")
    def _ordered(self) -> PostureModel:
        for name in ("upper_arm", "trunk"):
            low, high = getattr(self, name)
            if low >= high:
                raise ValueError(f"{name}: the yellow onset must be below the red one")
        return self

    def build(self) -> PostureZones:
        return PostureZones((self.upper_arm[0], self.upper_arm[1]),
                            (self.trunk[0], self.trunk[1]),
                            Sourced(self.source, self.provenance))


_STRETCH = StretchModel(margin=1.25, source=(
    "the part's max_axial_strain (its datasheet or a pull test) is red; yellow within 80 % "
    "of it, an engineering choice for model and parameter uncertainty"))


class RulesFile(_Strict):
    schema_: int = Field(alias="schema", ge=1, le=1)
    zones: ZonesModel
    hand: HandModel
    capacity: list[CapacityModel] = Field(min_length=1)
    tool: ToolModel
    kind: list[KindModel] = Field(min_length=1)
    bend: BendModel
    kink: KinkModel
    twist: TwistModel
    stretch: StretchModel = _STRETCH  # optional: tables written before it still load
    packaging: PackagingModel | None = None  # optional: the bundled limits when left out
    access: AccessModel | None = None  # optional: the bundled hand when left out
    body: BodyModel | None = None  # optional: the bundled population when left out
    posture: PostureModel | None = None  # optional: the bundled zones when left out

    @model_validator(mode="after")
    def _consistent(self) -> RulesFile:
        ids = [c.id.lower() for c in self.capacity]
        for row in ("palm push", "power grip", "wrist twist", "hand bending", "pinch",
                    "two-hand push"):
            if row not in ids:
                raise ValueError(f"capacity: no row with id {row!r} (every grip check "
                                 "needs one)")
        if len(set(ids)) != len(ids):
            raise ValueError("capacity: two rows share an id")
        kinds = [k.id.lower() for k in self.kind]
        if len(set(kinds)) != len(kinds):
            raise ValueError("kind: two kinds share an id")
        for lo, hi, name in ((self.tool.green, self.tool.yellow, "tool"),
                             (self.kink.yellow, self.kink.red, "kink"),
                             (self.twist.yellow, self.twist.red, "twist")):
            if lo >= hi:
                raise ValueError(f"{name}: the yellow (or green) limit must be below the "
                                 "next one")
        return self

    def build(self, origin: str) -> Rules:
        z = self.zones
        return Rules(
            zones_green=z.green, zones_yellow=z.yellow, zones=Sourced(z.source, z.provenance),
            hand_friction=self.hand.friction,
            hand=Sourced(self.hand.friction_source, self.hand.friction_provenance),
            capacities={c.id.lower(): c.build(z) for c in self.capacity},
            tool_green=self.tool.green, tool_yellow=self.tool.yellow,
            tool=Sourced(self.tool.source, self.tool.provenance),
            kinds={k.id.lower(): k.build() for k in self.kind},
            bend_margin=self.bend.margin,
            bend_margin_sourced=Sourced(self.bend.margin_source, "engineering choice"),
            fitting_straight=self.bend.fitting_straight, fitting_tight=self.bend.fitting_tight,
            fitting=Sourced(self.bend.fitting_source, "vendor rule"),
            kink_yellow=self.kink.yellow, kink_red=self.kink.red,
            kink_min_ratio=self.kink.min_ratio, kink=Sourced(self.kink.source, "derived"),
            twist_yellow=self.twist.yellow, twist_red=self.twist.red,
            twist=Sourced(self.twist.source, "standard"),
            stretch_margin=self.stretch.margin,
            stretch=Sourced(self.stretch.source, "engineering choice"),
            packaging=(bundled_rules().packaging if self.packaging is None
                       else self.packaging.build()),
            access=(self.access.build() if self.access is not None
                    else None if origin == "bundled rules" else bundled_rules().access),
            body=(self.body.build() if self.body is not None
                  else None if origin == "bundled rules" else bundled_rules().body),
            posture=(self.posture.build() if self.posture is not None
                     else None if origin == "bundled rules" else bundled_rules().posture),
            origin=origin)


def parse_rules(text: str, source: str = "<string>") -> Rules:
    """Rules from TOML text; errors name the source and the field."""
    data = read_toml(text, source)
    try:
        model = RulesFile.model_validate(data)
    except ValidationError as err:
        first = err.errors()[0]
        where = field_path(tuple(first["loc"]))
        if where.startswith("capacity[") and "id" not in where:
            rows = data.get("capacity", [])
            index = first["loc"][1] if len(first["loc"]) > 1 else None
            if isinstance(index, int) and index < len(rows) and isinstance(rows[index], dict):
                where += f" (row {rows[index].get('id', '?')!r})"
        message = first["msg"].removeprefix("Value error, ")
        if first["type"] == "missing":
            message = "missing: every row names its value, unit, source and provenance"
        raise FileFormatError(f"{source}: {where}: {message}") from None
    return model.build(source)


@cache
def bundled_rules() -> Rules:
    """The bundled table, ``pliant/data/rules.toml``."""
    text = resources.files("pliant.data").joinpath("rules.toml").read_text("utf-8")
    return parse_rules(text, "bundled rules")


def load_rules(path: str | Path | None = None) -> Rules:
    """A rules file (TOML), or the bundled table when ``path`` is None."""
    if path is None:
        return bundled_rules()
    path = Path(path)
    return parse_rules(read_text(path, "rules file"), str(path))
