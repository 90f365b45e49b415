"""What the MuJoCo plant needs from a URDF: each joint's effort limit and each moved link's inertia.

Checked once, when the plant is reset for a run, so a URDF that cannot be simulated is one
line naming the joint or link before any step.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from collections.abc import Sequence

import numpy as np

from otmm_qp.exceptions import ConfigError
from otmm_qp.robots.robot import FloatArray

__all__ = ["effort_limits"]


def _effort(joint: ET.Element) -> float | None:
    limit = joint.find("limit")
    if limit is None or limit.get("effort") is None:
        return None
    try:
        value = float(limit.get("effort", ""))
    except ValueError:
        return None
    return value if math.isfinite(value) and value > 0.0 else None


def effort_limits(
    urdf: str, joint_names: Sequence[str], default: float | None, field: str
) -> FloatArray:
    """Torque limits τ_max [N·m] (nv,) of the robot's joints, from their URDF ``effort``.

    Args:
        urdf: URDF text.
        joint_names: The robot's joints, in order.
        default: Limit used for a joint without a positive finite ``effort`` [N·m]; None
            refuses such a joint.
        field: Config path used in messages.

    Raises:
        ConfigError: The URDF is not XML, a joint is missing or has no effort limit (and no
            ``default``), or the child link of a robot joint has no ``<inertial>`` with a
            positive mass (no default inertia is used).
    """
    try:
        root = ET.fromstring(urdf)
    except ET.ParseError as error:
        raise ConfigError(field, f"the robot's URDF is not XML: {error}") from None
    joints = {j.get("name"): j for j in root.findall("joint")}  # not <transmission> joints
    links = {link.get("name"): link for link in root.findall("link")}
    limits = np.zeros(len(joint_names))
    for i, name in enumerate(joint_names):
        joint = joints.get(name)
        if joint is None:
            raise ConfigError(field, f"joint {name!r} is not in the robot's URDF")
        effort = _effort(joint)
        if effort is None:
            if default is None:
                raise ConfigError(
                    f"{field}.effort_limit" if field else "effort_limit",
                    f"joint {name!r} has no positive effort limit in the URDF; set "
                    "effort_limit [N·m] to use one for such joints (no default is used)",
                )
            effort = default
        limits[i] = effort
        child = joint.find("child")
        link = links.get(child.get("link") if child is not None else None)
        inertial = link.find("inertial") if link is not None else None
        mass = inertial.find("mass") if inertial is not None else None
        try:
            mass_value = float(mass.get("value", "nan")) if mass is not None else math.nan
        except ValueError:
            mass_value = math.nan
        if not (math.isfinite(mass_value) and mass_value > 0.0):
            link_name = child.get("link") if child is not None else "?"
            raise ConfigError(
                field,
                f"link {link_name!r} (moved by joint {name!r}) has no <inertial> with a "
                "positive mass in the URDF; MuJoCo needs it (no default inertia is used)",
            )
    return limits
