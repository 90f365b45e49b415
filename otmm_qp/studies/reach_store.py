"""The certified reaches of a study's robots, stored with its results.

``DIR/certificates/reach-<key>.json``, for every robot of a study with a reference: the
frame's certified reach (:func:`~otmm_qp.reference.reach.certified_reach`) and the reaches of
the joint origins the tool carries (:func:`~otmm_qp.reference.wrist.carried_points`), each
keyed by a hash of its chain, frame and joint limits (:func:`~otmm_qp.reference.reach.
model_key`: a changed URDF, frame or limit is another file). Written once, before any episode
runs, atomically; a stored one is read instead of computed. The workers, which need not see
the folder, compute the same numbers (the search is deterministic and bounded by counts).
"""

from __future__ import annotations

from pathlib import Path

from otmm_qp.exceptions import OtmmError
from otmm_qp.paths import ensure_inside
from otmm_qp.reference.reach import DegenerateReach, certified_reach
from otmm_qp.reference.wrist import carried_points
from otmm_qp.studies.schema import StudyConfig
from otmm_qp.studies.storage import StudyDirectoryError
from otmm_qp.studies.task import BuildCache

#: The study folder's subfolder of certificates.
CERTIFICATES = "certificates"


def store_reaches(config: StudyConfig, out: Path) -> list[Path]:
    """Compute (or read) and store the certified reaches of every robot of the study.

    Nothing for a study without a reference. A robot that cannot be built or has no finite
    reach is left out (its tasks' rows say why).

    Returns:
        The certificate files in ``out/certificates``, sorted.

    Raises:
        OutputPathError: ``out/certificates`` resolves outside ``out`` (a symlink).
        StudyDirectoryError: It cannot be written (disk full, permissions).
    """
    if not config.reference.enabled:
        return []
    folder = out / CERTIFICATES
    ensure_inside(out, folder)
    cache = BuildCache()
    for index in range(len(config.robots)):
        try:
            robot = cache.robot(config, index)
        except (OtmmError, ValueError, OSError):
            continue  # the robot's tasks fail with the reason
        try:
            certified_reach(robot, folder)
            carried_points(robot, folder)
        except DegenerateReach:
            continue
        except OSError as error:
            raise StudyDirectoryError(str(folder), f"cannot write: {error.strerror}") from None
    return sorted(folder.glob("reach-*.json")) if folder.is_dir() else []
