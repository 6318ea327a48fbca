"""Validated configuration of the whole pipeline, one section per stage (requirement SR-CFG-*).

The defaults live here, in code; a TOML file given with ``--config FILE`` overrides any subset
of them (a table per section, e.g. ``[cluster] eps_m = 0.2``). Every field carries its unit in
its name. Validation is strict: an unknown key, a wrong type or a value outside its allowed
range raises :class:`~pipeline.errors.ConfigError` whose lines each name the key, the value and
what is allowed. :func:`config_hash` is a stable SHA-256 over the canonical JSON form of the
values, recorded in every evidence bundle and audit log.
"""

from __future__ import annotations

import hashlib
import json
import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any, Literal

from annotated_types import Ge, Gt, Le, Lt
from pydantic import BaseModel, ValidationError, model_validator
from pydantic.fields import FieldInfo

from pipeline.compat import tomllib
from pipeline.config.base import Section
from pipeline.config.sections_perception import (
    ClassifySection,
    ClusterSection,
    DriverSection,
    FusionSection,
    PredictSection,
    ScanSection,
    SecondScanSection,
    TrackSection,
)
from pipeline.config.sections_safety import (
    AuditSection,
    CostmapSection,
    GeometrySection,
    GovernorSection,
    MonitorSection,
    RuntimeSection,
    StoppingSection,
)
from pipeline.config.sections_sensors import (
    AcousticSection,
    MapSection,
    MarkingsSection,
    RadarSection,
    ThermalSection,
)
from pipeline.config.sections_sim import CampaignSection, SimSection
from pipeline.errors import ConfigError

__all__ = [
    "AcousticSection",
    "AuditSection",
    "CampaignSection",
    "ClassifySection",
    "ClusterSection",
    "CostmapSection",
    "DriverSection",
    "FusionSection",
    "GeometrySection",
    "GovernorSection",
    "MapSection",
    "MarkingsSection",
    "MonitorSection",
    "PredictSection",
    "RadarSection",
    "RuntimeSection",
    "SafecaseConfig",
    "ScanSection",
    "SecondScanSection",
    "SimSection",
    "StoppingSection",
    "ThermalSection",
    "TrackSection",
    "config_hash",
    "default_config",
    "load_config",
    "overridden",
    "to_toml",
    "validate_config",
]


class SafecaseConfig(Section):
    """The whole configuration: one section per stage of the data path."""

    driver: DriverSection = DriverSection()
    scan: ScanSection = ScanSection()
    scan2: SecondScanSection = SecondScanSection()
    cluster: ClusterSection = ClusterSection()
    track: TrackSection = TrackSection()
    classify: ClassifySection = ClassifySection()
    predict: PredictSection = PredictSection()
    stopping: StoppingSection = StoppingSection()
    governor: GovernorSection = GovernorSection()
    geometry: GeometrySection = GeometrySection()
    costmap: CostmapSection = CostmapSection()
    fusion: FusionSection = FusionSection()
    monitors: MonitorSection = MonitorSection()
    sim: SimSection = SimSection()
    campaign: CampaignSection = CampaignSection()
    audit: AuditSection = AuditSection()
    runtime: RuntimeSection = RuntimeSection()
    thermal: ThermalSection = ThermalSection()
    radar: RadarSection = RadarSection()
    acoustic: AcousticSection = AcousticSection()
    markings: MarkingsSection = MarkingsSection()
    map: MapSection = MapSection()

    @model_validator(mode="after")
    def _monitor_enforces_the_proved_latency(self) -> SafecaseConfig:
        # SR-STOP-5: the stopping proof assumes data at most perception_latency_s old at
        # decision time; the freshness monitor is what guarantees it, so it may not allow more.
        if self.monitors.scan_max_age_s > self.stopping.perception_latency_s:
            raise ValueError(
                f"monitors.scan_max_age_s ({self.monitors.scan_max_age_s}) must not exceed "
                f"stopping.perception_latency_s ({self.stopping.perception_latency_s}): the "
                "monitor would pass data older than the stopping proof assumes"
            )
        return self

    @model_validator(mode="after")
    def _map_cannot_cover_a_person(self) -> SafecaseConfig:
        # SR-AVL-8: a covered point lies within tolerance + sqrt(2) resolution of the structure;
        # that reach must stay below a person's radius, or a person standing clear of the
        # racking could be taken for it.
        m = self.map
        reach = m.tolerance_m + math.sqrt(2.0) * m.resolution_m
        if reach >= self.runtime.person_radius_m:
            raise ValueError(
                f"map.tolerance_m + sqrt(2) map.resolution_m ({reach:.4g}) must be below "
                f"runtime.person_radius_m ({self.runtime.person_radius_m})"
            )
        return self

    @model_validator(mode="after")
    def _thermal_only_pedestrians_are_cautious(self) -> SafecaseConfig:
        # SR-FUS-3: a thermal-only pedestrian must get the most cautious margin tier, so its
        # confidence must stay below the medium tier's threshold.
        f, c = self.fusion, self.classify
        if f.thermal_only_confidence >= c.medium_confidence_min:
            raise ValueError(
                f"fusion.thermal_only_confidence ({f.thermal_only_confidence}) must be below "
                f"classify.medium_confidence_min ({c.medium_confidence_min}) so that "
                "thermal-only pedestrians get the most cautious margin tier"
            )
        return self

    @model_validator(mode="after")
    def _sensor_streams_stay_fresh(self) -> SafecaseConfig:
        # SR-FUS-1, SR-FUS-9: a capture is fused while its age stays within max_age - skew; a
        # sensor whose period exceeds that goes stale between two captures, every period.
        f = self.fusion
        for sensor, rate_hz, age_key in (
            ("thermal", self.thermal.rate_hz, "thermal_max_age_s"),
            ("radar", self.radar.rate_hz, "radar_max_age_s"),
        ):
            window_s = getattr(f, age_key) - f.clock_skew_s
            if 1.0 / rate_hz > window_s:
                raise ValueError(
                    f"{sensor}.rate_hz = {rate_hz!r}: allowed: at least {1.0 / window_s:.4g} "
                    f"(1 / (fusion.{age_key} - fusion.clock_skew_s) = 1 / ({getattr(f, age_key)} "
                    f"- {f.clock_skew_s})): each capture would go stale before the next one"
                )
        return self

    @model_validator(mode="after")
    def _footprint_holds_the_robot(self) -> SafecaseConfig:
        # The governor and the planner check the configured footprint; the simulated robot
        # must fit inside it, or the closed loop would certify a smaller robot than it drives.
        g, s = self.geometry, self.sim
        if s.ego_length_m > g.footprint_length_m or s.ego_width_m > g.footprint_width_m:
            raise ValueError(
                f"sim.ego_length_m x sim.ego_width_m ({s.ego_length_m} x {s.ego_width_m}) must "
                f"fit in geometry.footprint_length_m x geometry.footprint_width_m "
                f"({g.footprint_length_m} x {g.footprint_width_m})"
            )
        return self

    @model_validator(mode="before")
    @classmethod
    def _reject_non_finite(cls, data: Any) -> Any:
        # pydantic accepts nan/inf for plain float fields with no bound; no safety parameter
        # may be non-finite, so reject them here with the key named.
        if isinstance(data, Mapping):
            for section, values in data.items():
                if isinstance(values, Mapping):
                    for key, value in values.items():
                        if isinstance(value, float) and not math.isfinite(value):
                            raise ConfigError(
                                [f"{section}.{key} = {value!r}: allowed: a finite number"]
                            )
        return data


def _toml_value(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int | float):
        return repr(value)
    if isinstance(value, str):
        return json.dumps(value)  # a JSON string is a valid TOML basic string
    if isinstance(value, list | tuple):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    raise TypeError(f"to_toml: cannot write {type(value).__name__} value {value!r}")


def to_toml(data: Mapping[str, Mapping[str, Any]]) -> str:
    """Write section tables of scalars and lists of scalars as TOML (what ``load_config`` reads
    back)."""
    lines: list[str] = []
    for section, values in data.items():
        lines.append(f"[{section}]")
        lines.extend(f"{key} = {_toml_value(value)}" for key, value in values.items())
        lines.append("")
    return "\n".join(lines)


def default_config() -> SafecaseConfig:
    """The built-in configuration (every default from code)."""
    return SafecaseConfig()


def config_hash(config: SafecaseConfig) -> str:
    """Stable SHA-256 (hex) of the configuration's values, independent of key order."""
    canonical = json.dumps(
        config.model_dump(mode="json"), sort_keys=True, separators=(",", ":"), allow_nan=False
    )
    return hashlib.sha256(canonical.encode("utf-8")).hexdigest()


def _field_info(loc: tuple[int | str, ...]) -> FieldInfo | None:
    model: type[BaseModel] = SafecaseConfig
    info: FieldInfo | None = None
    for part in loc:
        if not isinstance(part, str) or part not in model.model_fields:
            return None
        info = model.model_fields[part]
        annotation = info.annotation
        if isinstance(annotation, type) and issubclass(annotation, BaseModel):
            model = annotation
    return info


def _allowed(loc: tuple[int | str, ...], err_type: str) -> str:
    """Describe what a key accepts, from the field's own declaration."""
    if err_type == "extra_forbidden":
        parent: type[BaseModel] = SafecaseConfig
        for part in loc[:-1]:
            info = parent.model_fields.get(str(part))
            if info is None or not (
                isinstance(info.annotation, type) and issubclass(info.annotation, BaseModel)
            ):
                break
            parent = info.annotation
        return "one of the keys " + ", ".join(sorted(parent.model_fields))
    info = _field_info(loc)
    if info is None:
        return "see `safecase config show` for the keys and defaults"
    bounds: list[str] = []
    for meta in info.metadata:
        if isinstance(meta, Ge):
            bounds.append(f">= {meta.ge}")
        elif isinstance(meta, Gt):
            bounds.append(f"> {meta.gt}")
        elif isinstance(meta, Le):
            bounds.append(f"<= {meta.le}")
        elif isinstance(meta, Lt):
            bounds.append(f"< {meta.lt}")
    annotation = info.annotation
    kind = {"float": "number", "int": "integer", "str": "string", "bool": "boolean"}.get(
        getattr(annotation, "__name__", ""), str(annotation)
    )
    article = "an" if kind[:1] in "aeiou" else "a"
    if getattr(annotation, "__origin__", None) is Literal:
        return "one of " + ", ".join(repr(a) for a in annotation.__args__)  # type: ignore[union-attr]
    if bounds:
        return f"{article} {kind} " + " and ".join(bounds)
    return f"{article} {kind}"


def _format_errors(error: ValidationError, origin: str) -> list[str]:
    lines = []
    for item in error.errors(include_url=False):
        loc = tuple(item["loc"])
        key = ".".join(str(p) for p in loc) or "<top level>"
        value = item.get("input")
        shown = "<missing>" if item["type"] == "missing" else repr(value)
        if item["type"] == "extra_forbidden":
            lines.append(f"{origin}: unknown key {key}; allowed: {_allowed(loc, item['type'])}")
            continue
        message = str(item["msg"])
        if item["type"] == "value_error" and "ctx" in item:
            lines.append(f"{origin}: {message.removeprefix('Value error, ')}")
            continue
        lines.append(
            f"{origin}: {key} = {shown}: {message}; allowed: {_allowed(loc, item['type'])}"
        )
    return lines


def validate_config(data: Mapping[str, Any], origin: str = "config") -> SafecaseConfig:
    """Build a :class:`SafecaseConfig` from nested mappings (sections of keys).

    Raises :class:`ConfigError` naming every bad key, its value and what is allowed.
    """
    try:
        return SafecaseConfig.model_validate(dict(data))
    except ConfigError as exc:
        raise ConfigError([f"{origin}: {line}" for line in exc.lines]) from None
    except ValidationError as exc:
        raise ConfigError(_format_errors(exc, origin)) from None


# A configuration is a few kilobytes; anything far larger is not one (and /dev/zero never ends).
MAX_CONFIG_BYTES = 1 << 20


def load_config(path: Path | str | None = None) -> SafecaseConfig:
    """Load the defaults, overridden by the TOML file at ``path`` when given (SR-CFG-1)."""
    if path is None:
        return default_config()
    file = Path(path)
    try:
        if not file.is_file():
            what = "a folder" if file.is_dir() else "not a regular file"
            if not file.exists():
                what = "no such file"
            raise ConfigError([f"{file}: cannot read the configuration file: {what}"])
        with file.open("rb") as handle:
            raw = handle.read(MAX_CONFIG_BYTES + 1)
    except OSError as exc:
        raise ConfigError([f"{file}: cannot read the configuration file: {exc.strerror}"]) from None
    if len(raw) > MAX_CONFIG_BYTES:
        raise ConfigError([f"{file}: larger than {MAX_CONFIG_BYTES} bytes: not a configuration"])
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise ConfigError(
            [f"{file}: not UTF-8 text (byte {exc.start}: {raw[exc.start : exc.start + 1]!r})"]
        ) from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError([f"{file}: not valid TOML: {exc}"]) from None
    except RecursionError:
        raise ConfigError([f"{file}: not valid TOML: nested too deeply"]) from None
    return validate_config(data, origin=str(file))


def overridden(config: SafecaseConfig, updates: Mapping[str, Mapping[str, Any]]) -> SafecaseConfig:
    """A copy of ``config`` with section values replaced, validated like a file would be."""
    data: dict[str, Any] = config.model_dump(mode="python")
    for section, values in updates.items():
        merged = dict(data.get(section, {}))
        merged.update(values)
        data[section] = merged
    return validate_config(data, origin="override")
