"""The certified reaches stored with a study (``DIR/certificates/reach-<key>.json``)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from otmm_qp.reference.reach import certified_reach
from otmm_qp.reference.wrist import carried_points
from otmm_qp.robots.pinocchio_arm import PinocchioArm
from otmm_qp.studies.execute import run_study
from otmm_qp.studies.reach_store import CERTIFICATES, store_reaches
from otmm_qp.studies.spec import parse_study, plan_study
from otmm_qp.studies.storage import StudyDirectoryError
from tests.factories import reference_study

UR5 = {"name": "ur5", "robot": {"type": "pinocchio", "name": "ur5", "task": "pose"}}
STUDY = reference_study(
    "reach-store",
    seed=5,
    chunk_size=2,
    generators=[{"type": "random_reachable", "count": 1, "duration": [0.4, 0.6]}],
    controllers=[{"name": "dls", "backend": {"type": "dls"}}],
    robots=[UR5],
)


def test_a_study_stores_the_reaches_of_its_robots(tmp_path: Path) -> None:
    out = tmp_path / "study"
    run_study(plan_study(parse_study(STUDY)), out, "test", workers=1)
    files = sorted((out / CERTIFICATES).glob("reach-*.json"))
    robot = PinocchioArm("ur5", task="pose")
    outers = {json.loads(f.read_text())["outer"] for f in files}
    expected = {certified_reach(robot).outer, *(p.outer for p in carried_points(robot))}
    assert len(files) == 3 and outers == expected  # the frame and the two carried points
    # stored once: a second run (resume) reads them, the files are not rewritten
    stamps = [f.stat().st_mtime_ns for f in files]
    run_study(plan_study(parse_study(STUDY)), out, "test", workers=1)
    assert [f.stat().st_mtime_ns for f in files] == stamps


def test_no_certificates_without_a_reference(tmp_path: Path) -> None:
    config = parse_study(dict(STUDY, reference={"enabled": False}))
    assert store_reaches(config, tmp_path) == []
    assert not (tmp_path / CERTIFICATES).exists()


def test_a_stored_certificate_is_read_not_recomputed(tmp_path: Path) -> None:
    """A file in the folder is what the study uses (its key names its chain and limits)."""
    config = parse_study(STUDY)
    first = store_reaches(config, tmp_path)
    assert first and all(p.parent == tmp_path / CERTIFICATES for p in first)
    assert store_reaches(config, tmp_path) == first


def test_an_unwritable_folder_is_one_typed_error(tmp_path: Path) -> None:
    (tmp_path / CERTIFICATES).write_text("a file where the folder goes")
    with pytest.raises(StudyDirectoryError, match="cannot write"):
        store_reaches(parse_study(STUDY), tmp_path)
