r"""A certified reach: an upper bound of ``max ‖p(q) − b‖`` over the joint box, by branch and bound.

``b`` is the first joint's origin (on its axis), ``p(q)`` the frame position of
:class:`~otmm_qp.reference.chain.Chain`, ``q`` in the box ``l ≤ q ≤ u`` of the position
limits (a revolute range of width ≥ 2π, or unbounded, is the circle ``[−π, π]``).

**Joints that cannot change the distance are fixed**: the first joint when it is revolute
(it turns ``p`` about an axis through ``b``), and from the frame backwards every revolute
joint whose axis passes within ``ON_AXIS`` of ``p`` (it turns ``p`` about itself; with ``d``
that distance it moves ``p`` by at most ``2d``, added to the bound).

**Enclosure** (second-order Taylor form of ``F = ‖p − b‖²`` on a box of centre ``c`` and
half-widths ``h``): with ``g = ∇F(c) = 2 J(c)ᵀ (p(c) − b)`` exact and a bound ``H_ij ≥
|∂²F/∂q_i∂q_j|`` valid everywhere,

.. math::
    \max_{|q - c| \le h} F(q) \le F(c) + \sum_i |g_i| h_i + \tfrac12 \sum_{ij} H_{ij} h_i h_j,
    \qquad H_{ij} = 2\,(\lambda_i \lambda_j + D\, \lambda_{\max(i,j)})

(``λ_i ≥ ‖∂p/∂q_i‖`` the chain's levers, ``D ≥ ‖p − b‖`` their sum;
``‖∂²p/∂q_i∂q_j‖ = ‖ω_i × (ω_j × (p − o_j))‖ ≤ λ_j`` for ``i ≤ j``).

**Branch and bound** (vectorised over boxes): every box's centre value is a lower bound of
the maximum (``found``), a box whose enclosure is ``≤ found`` is dropped, the others are
halved along the coordinate with the largest share of their enclosure's excess, until the
enclosures are within ``RELATIVE_GAP`` of ``found`` or ``MAX_BOXES`` boxes were evaluated.
A stopped search is still a valid bound (the largest enclosure left). The result is rounded
outward: relative and absolute room ``ROUNDING`` against the floating-point evaluation of
the kinematics, then ``np.nextafter`` upward.

Certified reaches are cached per model (:func:`model_key`: a hash of the chain's placements,
axes, frame and limits) in memory and, when a folder is given, in ``reach-<key>.json``
there (a study keeps them with its results); a changed URDF, frame or limit is another key.
"""

from __future__ import annotations

import hashlib
import json
import math
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from otmm_qp.paths import atomic_write_text
from otmm_qp.reference.chain import Chain, UnsupportedChain, chain_of
from otmm_qp.robots.robot import FloatArray, Robot

#: Stop once the largest enclosure of ``F`` is within this fraction of the best value found.
RELATIVE_GAP = 1e-6
#: Cap on the boxes evaluated (a stopped search still gives a valid, looser bound).
MAX_BOXES = 400_000
#: Pieces per free coordinate of the first grid of boxes.
FIRST_SPLIT = 4
#: Distance [m] from a joint axis below which the frame counts as on it (joint fixed).
ON_AXIS = 1e-9
#: Relative and absolute room [m] added to the bound against rounding.
ROUNDING = 1e-9
#: Bumped when the method changes, so stored certificates are recomputed.
VERSION = 1

_memory: dict[str, ReachCertificate] = {}


class DegenerateReach(ValueError):
    """No finite reach can be certified (unbounded prismatic joint, unreadable chain)."""


@dataclass(frozen=True)
class ReachCertificate:
    """A certified bound of how far a frame gets from a point of the first joint's axis.

    Attributes:
        key: :func:`model_key` of the robot it was computed for.
        base: ``b`` [m], shape ``(d,)``.
        outer: Certified ``max ‖p(q) − b‖`` over the joint box [m] (upper bound).
        found: Largest ``‖p(q) − b‖`` at an evaluated configuration [m] (lower bound of the
            maximum: the bound is tight to ``outer − found``).
        free: Chain joints searched over (the others cannot change the distance).
        boxes: Boxes evaluated.
        converged: The enclosures met ``RELATIVE_GAP`` (else the box cap stopped it).
    """

    key: str
    base: tuple[float, ...]
    outer: float
    found: float
    free: tuple[int, ...]
    boxes: int
    converged: bool


def joint_box(chain: Chain, robot: Robot) -> tuple[FloatArray, FloatArray]:
    """Chain joint bounds ``(lower, upper)`` [rad or m], a full circle capped to ``[−π, π]``.

    Raises:
        DegenerateReach: A prismatic joint of the chain without finite limits.
    """
    lower, upper = (np.asarray(v, dtype=float)[chain.columns] for v in robot.position_limits)
    circle = ~chain.prismatic & (~np.isfinite(upper - lower) | (upper - lower >= 2.0 * math.pi))
    lower = np.where(circle, -math.pi, lower)
    upper = np.where(circle, math.pi, upper)
    if not np.all(np.isfinite(lower) & np.isfinite(upper)):
        raise DegenerateReach("a prismatic joint without finite limits: the reach is unbounded")
    return lower, upper


def model_key(chain: Chain, lower: FloatArray, upper: FloatArray) -> str:
    """Hash of everything the certificate depends on (chain, frame, limits, method)."""
    digest = hashlib.sha256(f"reach-v{VERSION}".encode())
    for array in (chain.placements, chain.axes, chain.prismatic, chain.tip, lower, upper):
        digest.update(np.ascontiguousarray(array, dtype=float).tobytes())
    return digest.hexdigest()[:20]


def certified_reach(robot: Robot, store: Path | None = None) -> ReachCertificate:
    """The robot's certified reach (cached; see the module docstring).

    Args:
        robot: A planar or Pinocchio arm.
        store: Folder of stored certificates (read, and written atomically when computed).

    Raises:
        DegenerateReach: No finite reach exists or the chain cannot be read.
    """
    try:
        chain = chain_of(robot)
    except UnsupportedChain as error:
        raise DegenerateReach(str(error)) from error
    lower, upper = joint_box(chain, robot)
    return certify(chain, lower, upper, store)


def certify(
    chain: Chain, lower: FloatArray, upper: FloatArray, store: Path | None = None
) -> ReachCertificate:
    """:func:`search_reach` of a chain over a box, cached per :func:`model_key`.

    In memory and, given ``store``, in ``store/reach-<key>.json`` (read when present, else
    written atomically once computed).
    """
    key = model_key(chain, lower, upper)
    path = store / f"reach-{key}.json" if store is not None else None
    certificate = _memory.get(key)
    if certificate is None and path is not None:
        certificate = _read(path)
    if certificate is None:
        certificate = search_reach(chain, lower, upper, key)
    if path is not None and not path.exists():
        _write(path, certificate)
    _memory[key] = certificate
    return certificate


def _read(path: Path) -> ReachCertificate | None:
    try:
        data = json.loads(path.read_text())
        data["base"] = tuple(data["base"])
        data["free"] = tuple(data["free"])
        return ReachCertificate(**data)
    except (OSError, ValueError, TypeError, KeyError):
        return None


def _write(path: Path, certificate: ReachCertificate) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_write_text(path, json.dumps(asdict(certificate)))


def _fixed_joints(chain: Chain) -> tuple[list[int], float]:
    """Chain joints that cannot change ``‖p − b‖``, and the room ``Σ 2d`` [m] they leave.

    From the base: joint ``j`` while every joint before it is fixed and its axis passes
    within ``ON_AXIS`` of ``b`` (``b`` is then a fixed point of joint ``j − 1``'s frame, so
    the distance ``d`` is the same in every configuration; turning about an axis ``d`` from
    ``b`` changes ``‖p − b‖`` by at most ``2d``). From the frame: joint ``j`` while every
    joint after it is fixed and the frame is within ``ON_AXIS`` of its axis.
    """
    fixed: list[int] = []
    room = 0.0
    p, _, origins, omegas = chain.forward(np.zeros((1, chain.size)))
    base = origins[0, 0] if chain.size else p[0]
    drift = 0.0
    for j in range(chain.size):
        if chain.prismatic[j]:
            break
        distance = float(np.linalg.norm(np.cross(omegas[0, j], base - origins[0, j])))
        if distance > ON_AXIS:
            break
        fixed.append(j)
        room += 2.0 * distance
    drift = 0.0
    for j in range(chain.size - 1, 0, -1):
        if chain.prismatic[j] or j in fixed:
            break
        offset = p[0] - origins[0, j]
        distance = float(np.linalg.norm(np.cross(omegas[0, j], offset))) + drift
        if distance > ON_AXIS:
            break
        fixed.append(j)
        drift += distance
        room += 2.0 * distance
    return sorted(fixed), room


def search_reach(
    chain: Chain,
    lower: FloatArray,
    upper: FloatArray,
    key: str = "",
    max_boxes: int = MAX_BOXES,
) -> ReachCertificate:
    """Branch and bound of ``max ‖p − b‖`` over the box (the module docstring).

    Args:
        chain: The joints moving the frame.
        lower: Lower ends of their box [rad or m], shape ``(m,)``, finite.
        upper: Upper ends, shape ``(m,)``, finite.
        key: The :func:`model_key` recorded in the certificate.
        max_boxes: Stop after this many boxes (a valid, looser bound).
    """
    fixed, room = _fixed_joints(chain)
    free = [j for j in range(chain.size) if j not in fixed]
    zero = np.zeros((1, chain.size))
    _, _, origins, _ = chain.forward(zero)
    base = origins[0, 0] if chain.size else chain.forward(zero)[0][0]
    dim = chain.dim
    if not free:
        p = chain.forward(np.clip(zero, lower, upper))[0][0]
        value = float(np.linalg.norm(p[:dim] - base[:dim]))
        outer = _outward(value * value, room)
        return ReachCertificate(key, tuple(base[:dim]), outer, value, (), 1, True)
    levers = chain.levers(lower, upper)[free]
    spread = chain.spread(lower, upper)
    slides = chain.prismatic[free]
    later = np.maximum.outer(np.arange(len(free)), np.arange(len(free)))
    hessian = 2.0 * (np.outer(levers, levers) + spread * levers[later])
    lo, hi = lower[free], upper[free]
    fill = np.clip(0.0, lower, upper)
    edges = [np.linspace(a, b, FIRST_SPLIT + 1) for a, b in zip(lo, hi, strict=True)]
    mids = [0.5 * (e[1:] + e[:-1]) for e in edges]
    centres = np.stack(np.meshgrid(*mids, indexing="ij"), axis=-1).reshape(-1, len(free))
    halves = np.broadcast_to((hi - lo) / (2 * FIRST_SPLIT), centres.shape).copy()
    best = -math.inf
    boxes = 0
    converged = False
    while True:
        q = np.broadcast_to(fill, (centres.shape[0], chain.size)).copy()
        q[:, free] = centres
        p, _, origins, omegas = chain.forward(q)
        offset = p[:, :dim] - base[:dim]
        value = np.einsum("ij,ij->i", offset, offset)
        jacobian = chain.jacobian(p, origins, omegas)[:, free, :dim]
        gradient = 2.0 * np.einsum("mjd,md->mj", jacobian, offset)
        boxes += centres.shape[0]
        best = max(best, float(np.max(value)))
        linear = np.abs(gradient) * halves
        curvature = halves * (halves @ hessian)
        taylor = value + np.sum(linear, axis=1) + 0.5 * np.sum(curvature, axis=1)
        lipschitz = np.sqrt(value) + np.where(slides, halves, np.minimum(halves, 2.0)) @ levers
        enclosure = np.minimum(taylor, lipschitz * lipschitz)
        keep = enclosure > best
        top = float(np.max(enclosure[keep])) if np.any(keep) else best
        if top - best <= RELATIVE_GAP * best:
            converged = True
            break
        if boxes >= max_boxes:
            break
        centres, halves = _bisect(centres[keep], halves[keep], (linear + curvature)[keep])
    outer = min(_outward(max(top, best), room), _outward(spread * spread, 0.0))
    return ReachCertificate(
        key,
        tuple(float(v) for v in base[:dim]),
        outer,
        math.sqrt(best),
        tuple(free),
        boxes,
        converged,
    )


def _bisect(
    centres: FloatArray, halves: FloatArray, share: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """Halve every box along the coordinate of its largest ``share``."""
    axis = np.argmax(share, axis=1)
    rows = np.arange(centres.shape[0])
    halves = halves.copy()
    halves[rows, axis] *= 0.5
    left, right = centres.copy(), centres.copy()
    left[rows, axis] -= halves[rows, axis]
    right[rows, axis] += halves[rows, axis]
    return np.vstack([left, right]), np.vstack([halves, halves])


def _outward(squared: float, room: float) -> float:
    """``sqrt`` of a bound of ``F`` plus ``room``, rounded outward [m]."""
    value = math.sqrt(max(squared, 0.0) * (1.0 + ROUNDING)) + ROUNDING + room
    return float(np.nextafter(value * (1.0 + ROUNDING) + ROUNDING, math.inf))
