"""Study files meet the run files' guarantees (issue 19): one hardened reader, strict numbers,
one step cap, and stated bounds on the plan's size, all before any compute (exit 2, one line)."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
import yaml

from otmm_qp.cli import main
from otmm_qp.config import load
from otmm_qp.exceptions import ConfigError
from otmm_qp.studies.schema import StudyConfig
from otmm_qp.studies.spec import check_plan_size, load_study, plan_study
from tests.cli_errors import refusal_text

GOOD = {
    "name": "small",
    "dt": 0.05,
    "duration": {"extra": 0.2},
    "robots": [{"name": "planar2", "robot": {"type": "planar", "link_lengths": [1.0, 0.8]}}],
    "generators": [{"type": "near_singular", "count": 2, "duration": [1.0, 1.5]}],
    "controllers": [{"name": "pinv", "backend": {"type": "pinv"}}],
}
TEXT = yaml.safe_dump(GOOD, sort_keys=False)


def _with(**changes: object) -> str:
    return yaml.safe_dump({**GOOD, **changes}, sort_keys=False)


ALIAS_BOMB = "a: &a [x, x, x, x, x, x, x, x, x, x]\n" + "".join(
    f"{chr(98 + i)}: &{chr(98 + i)} [*{chr(97 + i)}, *{chr(97 + i)}, *{chr(97 + i)}, "
    f"*{chr(97 + i)}, *{chr(97 + i)}, *{chr(97 + i)}, *{chr(97 + i)}, *{chr(97 + i)}, "
    f"*{chr(97 + i)}, *{chr(97 + i)}]\n"
    for i in range(8)
)

HOSTILE: dict[str, tuple[str | bytes, str]] = {
    "alias bomb": (ALIAS_BOMB + TEXT, "more than 200000 values once aliases are expanded"),
    "deep nesting": (TEXT + "description: " + "[" * 60 + "]" * 60 + "\n", "nesting deeper"),
    "non-UTF-8": (TEXT.encode() + b"description: \xff\xfe\n", "not UTF-8"),
    "binary": (b"\x00\x01\x02" * 10, "malformed YAML|not UTF-8"),
    "duplicate dt": (TEXT + "dt: 0.01\n", "duplicate key 'dt'"),
    "over 1 MiB": (TEXT + "#" * (1 << 20) + "\n", "larger than 1048576 bytes"),
    "dt .inf": (TEXT.replace("dt: 0.05", "dt: .inf"), r"dt: Input should be a finite number"),
    "clik_gain .inf": (TEXT + "clik_gain: .inf\n", "clik_gain: Input should be a finite number"),
    "extra .inf": (_with(duration={"extra": float("inf")}), "duration.extra: Input should"),
    "success .nan": (_with(success={"max_position_error": float("nan")}), "success.max_position"),
    "task_weight .inf": (
        _with(robots=[{**GOOD["robots"][0], "task_weight": [float("inf"), 1.0]}]),  # type: ignore[dict-item]
        "robots.0.task_weight.0: Input should be a finite number",
    ),
    "zero weight": (
        _with(robots=[{**GOOD["robots"][0], "task_weight": [0.0, 1.0]}]),  # type: ignore[dict-item]
        "every task weight must be > 0",
    ),
    "repeated loop mode": (_with(loop_modes=["clik", "clik"]), "loop modes must be unique"),
    "tiny dt": (_with(dt=1.0e-9), r"duration/dt = .* exceeds max_steps = 1000000 .*GiB"),
    "max_steps": (_with(max_steps=5), r"exceeds max_steps = 5"),
    "10^9 tasks": (
        _with(generators=[{**GOOD["generators"][0], "count": 10**9}]),  # type: ignore[dict-item]
        r"1e\+09 tasks exceeds limits.max_tasks = 100000; raise limits.max_tasks",
    ),
    "10^30 tasks": (
        _with(generators=[{**GOOD["generators"][0], "count": 10**30}]),  # type: ignore[dict-item]
        r"limits.max_tasks",
    ),
    "10^6 grid": (
        _with(
            controllers=[
                {
                    "name": "otmm",
                    "filters": [{"type": "otmm"}],
                    "backend": {"type": "pinv"},
                    "grid": {"sigma_s": [0.01 + i * 1e-6 for i in range(1000)],
                             "p": ["linear"] * 1000},
                }
            ]
        ),
        r"grids expand to 1e\+06 controllers, more than limits.max_controllers = 1000",
    ),
    "10^9 budget": (
        _with(generators=[{**GOOD["generators"][0], "attempts": 10**9}]),  # type: ignore[dict-item]
        r"generators.0.attempts: 1e\+09 exceeds limits.max_generator_budget",
    ),
    "wrong-length acceleration_limit": (
        _with(
            controllers=[
                {
                    "name": "qp",
                    "backend": {
                        "type": "qp",
                        "limits": [{"type": "acceleration", "a_max": [1.0]}],
                    },
                }
            ]
        ),
        r"robots.0.controllers.0 \(qp\): ",
    ),
}  # fmt: skip


@pytest.mark.parametrize("case", sorted(HOSTILE))
def test_hostile_study_file_is_one_line_exit_2_before_compute(
    case: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    content, pattern = HOSTILE[case]
    path = tmp_path / "study.yaml"
    if isinstance(content, bytes):
        path.write_bytes(content)
    else:
        path.write_text(content)
    out = tmp_path / "out"
    status = main(["study", str(path), "--out", str(out), "--quiet", "--workers", "1"])
    err = refusal_text(capsys.readouterr().err)
    assert status == 2
    assert re.search(pattern, err), err
    assert not out.exists()  # refused before any compute


def test_limits_are_overridable_and_the_plan_matches_them(tmp_path: Path) -> None:
    path = tmp_path / "s.yaml"
    # 2 tasks × (1 controller × 1 loop mode + 1 reference) = 4 episodes, the plan's count
    path.write_text(_with(limits={"max_tasks": 2, "max_episodes": 4}))
    plan = plan_study(load_study(path))
    assert len(plan.episodes) == 4
    assert len([e for e in plan.episodes if e.is_reference]) == 2
    path.write_text(_with(limits={"max_tasks": 2, "max_episodes": 3}))
    with pytest.raises(ConfigError, match=re.escape(
        "2 tasks × (1 controllers × 1 loop modes + 1 reference) = 4 episodes exceeds "
        "limits.max_episodes = 3"
    )):  # fmt: skip
        plan_study(load_study(path))
    path.write_text(_with(limits={"max_tasks": 1}))
    with pytest.raises(Exception, match="limits.max_tasks = 1"):
        plan_study(load_study(path))


@pytest.mark.parametrize("reference", [True, False])
@pytest.mark.parametrize(
    ("count", "modes", "grid"), [(1, ["clik"], 1), (3, ["clik", "feedforward"], 2)]
)
def test_the_episode_bound_counts_exactly_the_planned_episodes(
    tmp_path: Path, reference: bool, count: int, modes: list[str], grid: int
) -> None:
    """``max_episodes = len(plan)`` passes and one less is refused, reference on or off."""
    controllers = [
        {"name": "pinv", "backend": {"type": "pinv"}},
        {"name": "dls", "backend": {"type": "dls"}, "grid": {"damping": [0.01, 0.05][:grid]}},
    ]
    text = _with(
        generators=[{"type": "near_singular", "count": count, "duration": [1.0, 1.5]}],
        controllers=controllers,
        loop_modes=modes,
        reference={"enabled": reference},
    )
    path = tmp_path / "s.yaml"
    path.write_text(text)
    size = len(plan_study(load_study(path)).episodes)
    assert size == count * ((1 + grid) * len(modes) + reference)
    config = load_study(path)
    check_plan_size(config.model_copy(update={"limits": config.limits.model_copy(
        update={"max_episodes": size})}))  # fmt: skip
    with pytest.raises(ConfigError, match=f"= {size} episodes exceeds limits.max_episodes"):
        check_plan_size(config.model_copy(update={"limits": config.limits.model_copy(
            update={"max_episodes": size - 1})}))  # fmt: skip


def test_one_loader_reads_run_and_study_files(tmp_path: Path) -> None:
    path = tmp_path / "s.yaml"
    path.write_text(TEXT)
    assert load(StudyConfig, path) == load_study(path)
    assert load_study(path).max_steps == 1_000_000  # the one step cap, shared with run files
