"""Parse a robot profile's ``auto_calibration`` section (schema version 2; see ``docs/profiles.md``)."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

from ..core.motor_models import MOTOR_MODELS, MotorModel, find_motor_model, motor_key
from ..core.profile_auto import (
    AUTO_STOPS,
    HARD_MAX_SPEED_DEG_S,
    HARD_MAX_TORQUE_FRACTION,
    AutoJoint,
    AutoSection,
)
from ..errors import FileFormatError
from ._numbers import parse_finite

__all__ = ["AUTO_KEYS", "check_known_keys", "parse_auto_section"]

AUTO_KEYS = (
    "speed_deg_s",
    "torque_fraction",
    "max_torque_fraction",
    "tolerance_deg",
    "span_tolerance_deg",
    "backoff_deg",
    "dwell_s",
    "second_touch",
    "joints",
)
_JOINT_KEYS = (
    "name",
    "stops",
    "lower_deg",
    "upper_deg",
    "tolerance_deg",
    "rated_nm",
    "motor",
    "torque_fraction",
    "speed_deg_s",
    "park_deg",
    "pose",
    "reason",
    "alongside",
)


def _alongside(row: Mapping[str, Any], out: list[AutoJoint], jw: str) -> AutoJoint | None:
    """The earlier joint ``row`` is searched at the same time as (``alongside``), or None."""
    other = row.get("alongside")
    if other is None:
        return None
    lead = next((j for j in out if j.name == other), None)
    if not isinstance(other, str) or lead is None:
        raise FileFormatError(
            f"{jw}: alongside {other!r} must name a joint earlier in the order (searched at the same time)"
        )
    if not lead.searched:
        raise FileFormatError(f"{jw}: alongside names {other!r}, which is not searched (stops: none)")
    if lead.alongside is not None:
        raise FileFormatError(
            f"{jw}: alongside names {other!r}, which is itself alongside {lead.alongside!r}: name that one"
        )
    return lead


def _check_holds(lead: AutoJoint, out: list[AutoJoint], pose: list[tuple[str, float]], jw: str) -> None:
    """The joints searched together must agree on the angles they hold."""
    held: dict[str, float] = {}
    for j in out:
        if j.name == lead.name or j.alongside == lead.name:
            held.update(j.pose)
    for other, angle in pose:
        if other in held and held[other] != angle:
            raise FileFormatError(
                f"{jw}: pose holds {other!r} at {angle:g}°, but {lead.name!r}, searched at the same time, "
                f"holds it at {held[other]:g}°"
            )


def check_known_keys(entry: Mapping[str, Any], allowed: tuple[str, ...], where: str) -> None:
    """Refuse a profile mapping with a key outside ``allowed`` (a typo must not be silently ignored).

    Raises:
        FileFormatError: The unknown keys and the expected ones, at ``where``.
    """
    extra = [str(k) for k in entry if k not in allowed]
    if extra:
        raise FileFormatError(f"{where}: unknown key {', '.join(extra)}; expected {', '.join(allowed)}")


def _num(entry: Mapping[str, Any], key: str, where: str, default: float | None) -> float | None:
    if entry.get(key) is None:
        return default
    value = entry[key]
    if isinstance(value, bool):
        raise FileFormatError(f"{where}: {key} {value!r} must be a number")
    return parse_finite(value, where, key)


def _positive(value: float | None, key: str, where: str, upper: float | None = None) -> float:
    if value is None or not value > 0:
        raise FileFormatError(f"{where}: {key} must be a positive number, got {value!r}")
    if upper is not None and value > upper:
        raise FileFormatError(f"{where}: {key} {value:g} is above the hard limit {upper:g}")
    return value


_LARGEST_RATED_NM = max(m.rated_nm for m in MOTOR_MODELS)
_SMALLEST_RATED_NM = 0.001
"""The least ``rated_nm`` a profile may give, N·m (no joint motor is rated below a millinewton-metre)."""


def _motor(row: Mapping[str, Any], joint_model: str | None, where: str) -> tuple[str | None, MotorModel | None]:
    """The motor model of a row: its ``motor`` key (a variant of the joint's bus model) or the joint's model."""
    named = row.get("motor")
    if named is None:
        return joint_model, find_motor_model(joint_model)
    if not isinstance(named, str) or find_motor_model(named) is None:
        known = ", ".join(m.name for m in MOTOR_MODELS)
        raise FileFormatError(f"{where}: motor {named!r} is not a motor model robocal knows ({known})")
    found = find_motor_model(named)
    assert found is not None
    if joint_model is not None and motor_key(joint_model) not in {motor_key(found.bus_model), motor_key(found.name)}:
        raise FileFormatError(
            f"{where}: motor {named!r} answers as {found.bus_model!r} on the bus, but the joint's model is "
            f"{joint_model!r}"
        )
    return found.name, found


def _rating(row: Mapping[str, Any], model: str | None, found: MotorModel | None, where: str) -> float | None:
    """The row's rating: the model's, or the profile's ``rated_nm`` when it is lower (never higher)."""
    given = _num(row, "rated_nm", where, None)
    if given is None:
        return None if found is None else found.rated_nm
    if not given >= _SMALLEST_RATED_NM:  # a cap of a fraction of a denormal rating would be 0 N·m
        raise FileFormatError(
            f"{where}: rated_nm must be a positive number (N·m) of at least {_SMALLEST_RATED_NM:g}, got {given!r}"
        )
    if found is not None and given > found.rated_nm:
        raise FileFormatError(
            f"{where}: rated_nm {given:g} N·m is above the {found.name}'s rated torque {found.rated_nm:g} N·m "
            f"({found.source}); a profile may lower a motor's rating, never raise it"
        )
    if found is None and given > _LARGEST_RATED_NM:
        raise FileFormatError(
            f"{where}: rated_nm {given:g} N·m is beyond any motor robocal knows (largest {_LARGEST_RATED_NM:g} N·m)"
        )
    return given


def _not_searched(
    row: Mapping[str, Any],
    name: str,
    reason: str,
    where: str,
    model: str | None,
    speed: float | None,
    tolerance: float | None,
) -> AutoJoint:
    """A ``stops: none`` entry: nothing moves, so only a reason (and no pose, torque or angles) goes with it."""
    moving = [k for k in ("torque_fraction", "speed_deg_s", "park_deg", "pose", "alongside") if row.get(k) is not None]
    if moving:
        raise FileFormatError(
            f"{where}: a joint that is not searched (stops: none) takes no {', '.join(moving)} (it never moves)"
        )
    if not reason:
        raise FileFormatError(f"{where}: stops: none needs a reason (why the joint has no hard stop)")
    motor, found = _motor(row, model, where)
    rated = _rating(row, motor, found, where)
    return AutoJoint(
        name=name,
        stops="none",
        rated_nm=0.0 if rated is None else rated,
        torque_fraction=0.0,
        speed_deg_s=speed or 10.0,
        tolerance_deg=tolerance or 15.0,
        lower_deg=_num(row, "lower_deg", where, None),
        upper_deg=_num(row, "upper_deg", where, None),
        reason=reason,
        motor=None if found is None else found.name,
    )


def parse_auto_section(data: Any, joints: Sequence[Any], source: str) -> AutoSection:
    """Validate the ``auto_calibration`` mapping of profile ``source``.

    Args:
        data: The loaded YAML value of the section.
        joints: The profile's joints (:class:`robocal.core.profile.ProfileJoint`), for names and models.
        source: Where the profile comes from (for messages).

    Raises:
        FileFormatError: Naming the profile, the joint and the field (a torque above the hard cap, a speed above
            the hard limit, a pose naming a joint not calibrated before, an unknown joint or key, ...).
    """
    where = f"profile {source}: auto_calibration"
    if not isinstance(data, Mapping):
        raise FileFormatError(f"{where}: expected a mapping with keys {', '.join(AUTO_KEYS)}")
    check_known_keys(data, AUTO_KEYS, where)
    cap = _positive(
        _num(data, "max_torque_fraction", where, 0.3), "max_torque_fraction", where, HARD_MAX_TORQUE_FRACTION
    )
    speed = _num(data, "speed_deg_s", where, 10.0)
    torque = _num(data, "torque_fraction", where, min(0.25, cap))
    tolerance = _num(data, "tolerance_deg", where, 15.0)
    span_tol = _positive(_num(data, "span_tolerance_deg", where, 10.0), "span_tolerance_deg", where, 90.0)
    backoff = _positive(_num(data, "backoff_deg", where, 5.0), "backoff_deg", where, 45.0)
    dwell = _positive(_num(data, "dwell_s", where, 0.2), "dwell_s", where, 5.0)
    second = data.get("second_touch", False)
    if not isinstance(second, bool):
        raise FileFormatError(f"{where}: second_touch {second!r}; expected true or false")
    models = {str(j.name): j.model for j in joints}
    rows = data.get("joints")
    if not isinstance(rows, list) or not rows:
        raise FileFormatError(f"{where}: joints must be a non-empty list (the search order)")
    out: list[AutoJoint] = []
    for i, row in enumerate(rows):
        jw = f"{where}: joints[{i}]"
        if not isinstance(row, Mapping):
            raise FileFormatError(f"{jw}: expected a mapping with keys {', '.join(_JOINT_KEYS)}")
        name = row.get("name")
        if not isinstance(name, str) or not name.strip():
            raise FileFormatError(f"{jw}: missing key name")
        name = name.strip()
        jw = f"{where}: joint {name!r}"
        check_known_keys(row, _JOINT_KEYS, jw)
        if name not in models:
            raise FileFormatError(f"{jw}: not a joint of the profile ({', '.join(models)})")
        if any(j.name == name for j in out):
            raise FileFormatError(f"{jw}: appears twice")
        stops = row.get("stops", "both")
        if stops not in AUTO_STOPS:
            raise FileFormatError(f"{jw}: stops {stops!r}; expected one of {', '.join(AUTO_STOPS)}")
        lower = _num(row, "lower_deg", jw, None)
        upper = _num(row, "upper_deg", jw, None)
        if lower is not None and upper is not None and not lower < upper:
            raise FileFormatError(f"{jw}: lower_deg {lower:g} must be below upper_deg {upper:g}")
        if (stops == "lower" and lower is None) or (stops == "upper" and upper is None):
            raise FileFormatError(
                f"{jw}: a one-sided joint (stops: {stops}) needs {stops}_deg, its stop angle"
            )
        reason = row.get("reason", "")
        if not isinstance(reason, str):
            raise FileFormatError(f"{jw}: reason must be text, not {reason!r}")
        if stops == "none":
            out.append(_not_searched(row, name, reason.strip(), jw, models[name], speed, tolerance))
            continue
        if reason:
            raise FileFormatError(f"{jw}: reason is for joints that are not searched (stops: none)")
        motor, found = _motor(row, models[name], jw)
        if found is None:
            known = ", ".join(m.name for m in MOTOR_MODELS)
            raise FileFormatError(
                f"{jw}: motor model {motor!r} has no known rating; a searched joint's torque is a fraction of its "
                f"motor's rating: give the joint a model robocal knows ({known}), or name it with motor:"
            )
        rated = _rating(row, motor, found, jw)
        assert rated is not None
        frac = _positive(_num(row, "torque_fraction", jw, torque), "torque_fraction", jw)
        if frac > cap:
            raise FileFormatError(
                f"{jw}: torque_fraction {frac:g} is above the profile's max_torque_fraction {cap:g}"
            )
        spd = _positive(_num(row, "speed_deg_s", jw, speed), "speed_deg_s", jw, HARD_MAX_SPEED_DEG_S)
        tol = _positive(_num(row, "tolerance_deg", jw, tolerance), "tolerance_deg", jw, 90.0)
        park = _num(row, "park_deg", jw, None)
        pose_raw = row.get("pose") or {}
        if not isinstance(pose_raw, Mapping):
            raise FileFormatError(f"{jw}: pose must map joint names to angles in degrees")
        alongside = _alongside(row, out, jw)
        before = out if alongside is None else out[: [j.name for j in out].index(alongside.name)]
        done = {j.name for j in before if j.searched}
        pose: list[tuple[str, float]] = []
        for other in pose_raw:
            if any(j.name == other and not j.searched for j in out):
                raise FileFormatError(f"{jw}: pose names {other!r}, which is not searched (stops: none)")
            if other not in done:
                raise FileFormatError(
                    f"{jw}: pose names {other!r}, which is not calibrated before it (only joints earlier in "
                    "the order can hold an angle)"
                )
            value = _num(pose_raw, other, f"{jw}: pose", None)
            assert value is not None
            pose.append((str(other), value))
        if alongside is not None:
            _check_holds(alongside, out, pose, jw)
        out.append(
            AutoJoint(
                name=name,
                stops=str(stops),
                rated_nm=rated,
                torque_fraction=frac,
                speed_deg_s=spd,
                tolerance_deg=tol,
                lower_deg=lower,
                upper_deg=upper,
                park_deg=park,
                pose=tuple(pose),
                alongside=None if alongside is None else alongside.name,
                motor=found.name,
            )
        )
    if not any(j.searched for j in out):
        raise FileFormatError(f"{where}: every joint has stops: none; at least one must be searched")
    if not math.isfinite(cap):  # pragma: no cover - _positive refuses
        raise FileFormatError(f"{where}: max_torque_fraction must be finite")
    return AutoSection(
        joints=tuple(out),
        max_torque_fraction=cap,
        span_tolerance_deg=span_tol,
        backoff_deg=backoff,
        dwell_s=dwell,
        second_touch=second,
    )
