r"""Plant presets: the command path of real arms' streaming interfaces as stage lists.

``plant: {preset: NAME}`` (alone, or as one entry of a stage list) expands to the stages below,
in the controller's own period ``dt`` (a preset does not change ``dt``: its latency is counted
in control periods). Every number's source is in ``docs/plants.md``; each body is MuJoCo, so a
preset needs the arm's joint efforts (a URDF ``effort`` per joint).

==================  ===============================================================
``franka_fci``      libfranka's rate limiter at 7.5 rad/s² (the smallest of its per-joint
                    limits, for every joint); latency 1 period; libfranka's 100 Hz command
                    low-pass (τ = 1/(2π·100 Hz) ≈ 1.6 ms) at the 1 ms MuJoCo step, and
                    servos at 100 Hz
``franka_fci_raw``  as ``franka_fci`` with ``limit_rate`` off (libfranka's default): no
                    rate limiter; the FCI's thresholds on the command stream (Panda:
                    7.5 rad/s², 3750 rad/s³, the smallest per-joint ones) are checked
                    (``interface`` stage), not applied
``fr3_fci``         as ``franka_fci_raw`` with the FR3's thresholds, 10 rad/s² and
                    5000 rad/s³ on every joint (libfranka 0.15 ``rate_limiting.h``)
``ur_e_series``     latency 1 period; servoj look-ahead smoothing as a lag τ = ``lookahead``
                    (default 0.03 s, its smallest; ``{preset: ur_e_series, lookahead: 0.1}``);
                    MuJoCo servos at 300/(2π) ≈ 47.7 Hz (servoj's default gain 300 as
                    ω [1/s]), 2 ms step. At 500 Hz latency and lag reproduce the measured
                    servoj lag, ≈ 17 periods of 2 ms = 34 ms on a UR10e over RTDE with
                    lookahead 0.03 (2–3 periods, 4–6 ms, with ``sync()`` instead of servoj;
                    Universal_Robots_Client_Library issue #86; docs/plants.md)
``ur_cb3``          as ``ur_e_series`` with a latency of 2 periods (125 Hz, not 500 Hz)
==================  ===============================================================

Every preset body gives each joint a reflected rotor inertia (``armature``) of 0.1 kg·m², the
value of MuJoCo Menagerie's ``universal_robots_ur5e/ur5e.xml`` and
``franka_emika_panda/panda.xml``; no contact is simulated (``contacts: false``; the MuJoCo
plant's own default simulates them).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

from otmm_qp.exceptions import ConfigError

__all__ = [
    "ARMATURE",
    "LOOKAHEAD_KEY",
    "FR3_ACCELERATION",
    "FR3_JERK",
    "FCI_PERIOD",
    "FRANKA_ACCELERATION",
    "FRANKA_JERK",
    "PRESETS",
    "PRESET_KEY",
    "expand_preset",
    "preset_lines",
]

#: The key of a preset entry.
PRESET_KEY = "preset"
#: servoj's ``lookahead_time`` [s] of a UR preset (its lag τ), and its allowed range (the UR
#: script manual: 0.03–0.2 s).
LOOKAHEAD_KEY = "lookahead"
LOOKAHEAD_RANGE = (0.03, 0.2)
LOOKAHEAD_PRESETS = ("ur_e_series", "ur_cb3")

#: libfranka's rate limit [rad/s²]: the smallest of its per-joint ``kMaxJointAcceleration``
#: (15, 7.5, 10, 12.5, 15, 20, 20; joint 2's), for every joint so the preset runs on any arm.
FRANKA_ACCELERATION = 7.5
#: The Panda's jerk limit [rad/s³]: the smallest of libfranka 0.9's ``kMaxJointJerk``
#: (7500, 3750, 5000, 6250, 7500, 10000, 10000; joint 2's).
FRANKA_JERK = 3750.0
#: The FR3's limits [rad/s²], [rad/s³]: libfranka 0.15 ``rate_limiting.h``,
#: ``kMaxJointAcceleration`` and ``kMaxJointJerk``, the same on every joint.
FR3_ACCELERATION = 10.0
FR3_JERK = 5000.0
#: The FCI's period [s]: libfranka's ``kDeltaT = 1e-3`` (``rate_limiting.h``).
FCI_PERIOD = 0.001

#: Reflected rotor inertia of every joint [kg·m²]: MuJoCo Menagerie's UR5e and Panda models.
ARMATURE = 0.1

_UR_SERVO = {"type": "mujoco", "frequency": 300.0 / (2.0 * math.pi), "damping_ratio": 1.0,
             "timestep": 0.002, "armature": ARMATURE, "contacts": False}  # fmt: skip

#: Preset name → its stages (``{type, **params}``), in order.
_FRANKA_BODY = ({"type": "delay", "steps": 1},
                {"type": "mujoco", "frequency": 100.0, "command_cutoff": 100.0,
                 "damping_ratio": 1.0, "timestep": 0.001, "armature": ARMATURE,
                 "contacts": False})  # fmt: skip

PRESETS: dict[str, tuple[Mapping[str, Any], ...]] = {
    "franka_fci": ({"type": "rate_limit", "acceleration": FRANKA_ACCELERATION}, *_FRANKA_BODY),
    "franka_fci_raw": (
        {
            "type": "interface",
            "acceleration": FRANKA_ACCELERATION,
            "jerk": FRANKA_JERK,
            "period": FCI_PERIOD,
        },
        *_FRANKA_BODY,
    ),
    "fr3_fci": (
        {
            "type": "interface",
            "acceleration": FR3_ACCELERATION,
            "jerk": FR3_JERK,
            "period": FCI_PERIOD,
        },
        *_FRANKA_BODY,
    ),
    "ur_e_series": (
        {"type": "delay", "steps": 1},
        {"type": "lag", "tau": 0.03},
        _UR_SERVO,
    ),
    "ur_cb3": (
        {"type": "delay", "steps": 2},
        {"type": "lag", "tau": 0.03},
        _UR_SERVO,
    ),
}


def expand_preset(block: Mapping[str, Any], field: str) -> list[Mapping[str, Any]]:
    """The stages of ``{preset: NAME}`` (a UR preset also takes ``lookahead``).

    ``lookahead`` [s] is servoj's ``lookahead_time``, in [0.03, 0.2] (the UR script manual's
    range), modelled as the lag's τ (default 0.03, the preset's own).

    Raises:
        ConfigError: An unknown name, other keys beside ``preset`` (and ``lookahead`` on a UR
            preset), or a ``lookahead`` out of range (one line, naming the field).
    """
    name = block[PRESET_KEY]
    allowed = {PRESET_KEY, LOOKAHEAD_KEY} if name in LOOKAHEAD_PRESETS else {PRESET_KEY}
    others = sorted(str(key) for key in block if key not in allowed)
    if others:
        raise ConfigError(
            field,
            f"a preset takes no other keys, got {', '.join(others)} (the UR presets take "
            f"{LOOKAHEAD_KEY}); list the stages to change one",
        )
    if not isinstance(name, str) or name not in PRESETS:
        raise ConfigError(
            f"{field}.{PRESET_KEY}",
            f"unknown preset {name!r}; available: {', '.join(sorted(PRESETS))}",
        )
    lookahead = block.get(LOOKAHEAD_KEY)
    if lookahead is not None:
        low, high = LOOKAHEAD_RANGE
        if (
            isinstance(lookahead, bool)
            or not isinstance(lookahead, int | float)
            or not low <= lookahead <= high
        ):
            raise ConfigError(
                f"{field}.{LOOKAHEAD_KEY}",
                f"must be a number in [{low:g}, {high:g}] s (servoj's lookahead_time), "
                f"got {lookahead!r:.40}",
            )
        return [
            dict(stage, tau=float(lookahead)) if stage["type"] == "lag" else dict(stage)
            for stage in PRESETS[name]
        ]
    return [dict(stage) for stage in PRESETS[name]]


def preset_lines(params: bool = False, names: Sequence[str] | None = None) -> list[str]:
    """One line per preset, ``NAME  stage → stage → …``; with ``params``, each stage's values.

    Args:
        params: Add an indented line per stage with its parameters.
        names: Only these presets (None: every one).
    """
    lines = []
    for name, stages in PRESETS.items():
        if names is not None and name not in names:
            continue
        lines.append(f"  {name:<24} {' → '.join(str(stage['type']) for stage in stages)}")
        if params:
            for stage in stages:
                values = ", ".join(f"{k}={v!r}" for k, v in stage.items() if k != "type")
                lines.append(f"      {stage['type']}: {values or '(no parameters)'}")
    return lines
