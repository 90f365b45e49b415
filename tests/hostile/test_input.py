"""Hostile input (issue 9): every bad input is one line naming the field, exit 2, nothing is
computed first, nothing is written outside --out, and earlier results survive."""

from __future__ import annotations

import re
from collections.abc import Callable
from pathlib import Path

import pytest

from otmm_qp import paths as paths_module
from otmm_qp.cli import main
from tests.cli_errors import refusal_text
from tests.factories import tiny_run

GOOD = tiny_run(duration=0.2)
QP = "backend: {type: qp, solver: daqp}"

ALIAS_BOMB = (
    "a: &a [x, x, x, x, x, x, x, x, x]\n"
    + "".join(
        f"{chr(98 + i)}: &{chr(98 + i)} [{', '.join(['*' + chr(97 + i)] * 9)}]\n" for i in range(8)
    )
    + GOOD.replace("loop_modes: [clik]", "loop_modes: *i")
)

#: (config text or bytes, pattern the one error line must match: it names the field).
CONFIG_CASES: dict[str, tuple[str | bytes, str]] = {
    # item 1, 2, 6, 7: names that would become paths
    "experiment ..": (GOOD.replace("name: A", "name: '..'"), r"experiments\.0\.name"),
    "experiment .hidden": (GOOD.replace("name: A", "name: .x"), r"experiments\.0\.name"),
    "experiment summary.csv": (GOOD.replace("name: A", "name: summary.csv"), r"summary"),
    "experiment report": (GOOD.replace("name: A", "name: report"), r"experiments\.0\.name"),
    "experiment 300 chars": (GOOD.replace("name: A", "name: " + "a" * 300), r"name"),
    # item 3, 10, 11, 12: the YAML itself
    "alias bomb": (ALIAS_BOMB, r"more than \d+ values once aliases are expanded"),
    "recursive alias": ("a: &a [*a]\n" + GOOD, r"(recursive|malformed YAML)"),
    "deep nesting": ("x: " + "[" * 1500 + "]" * 1500 + "\n" + GOOD, r"nesting deeper"),
    "duplicate key": (GOOD.replace("dt: 0.02", "dt: 0.02\ndt: 0.01"), r"duplicate key 'dt'"),
    "non-UTF-8": (GOOD.encode() + b"# \xff\xfe\n", r"not UTF-8 text \(byte 0xff"),
    "binary": (b"\x00\x01\x02\x03" * 10, r"(not UTF-8|malformed YAML|top level)"),
    "unhashable key": ("? [a, b]\n: 1\n" + GOOD, r"(plain value|malformed)"),
    "too large": ("# " + "x" * (1 << 20) + "\n" + GOOD, r"larger than"),
    "1e6 is a number": (GOOD.replace("duration: 0.2", "duration: 1e6"), r"duration.*max_steps"),
    "dt .inf": (GOOD.replace("dt: 0.02", "dt: .inf"), r"^dt|: dt: .*finite"),
    "dt .nan": (GOOD.replace("dt: 0.02", "dt: .nan"), r"dt: .*finite"),
    "duration .inf": (GOOD.replace("duration: 0.2", "duration: .inf"), r"duration: .*finite"),
    "clik_gain .inf": (GOOD.replace("dt: 0.02", "dt: 0.02\nclik_gain: .inf"), r"clik_gain"),
    "q0 nan": (GOOD.replace("[0.927, -2.5]", "[.nan, -2.5]"), r"q0\.0"),
    "q0 1e308": (GOOD.replace("[0.927, -2.5]", "[1.0e+308, -2.5]"), r"q0: every joint"),
    "task_weight inf": (
        GOOD.replace("duration: 0.2", "duration: 0.2\n    task_weight: [.inf, 1]"),
        r"task_weight\.0",
    ),
    "link_lengths 1e308": (
        GOOD.replace("[1.0, 0.8]", "[1.0e+308, 0.8]"),
        r"experiments\.0\.(robot|trajectory)",
    ),
    "velocity limit NaN": (
        GOOD.replace("[1.0, 0.8]}", "[1.0, 0.8], velocity_limits: [.nan, 1.0]}"),
        r"experiments\.0\.robot\.velocity_limits: every limit must be > 0",
    ),
    # issue 19: messages name the field and what it accepts
    "p a list": (
        GOOD.replace("p: linear", "p: [linear]"),
        r"filters\.0\.p: must be a p-function name \(.*linear.*\), got \['linear'\]",
    ),
    "string in link_lengths": (
        GOOD.replace("[1.0, 0.8]", "[one, 0.8]"),
        r"robot\.link_lengths\[0\]: input should be a valid number, got 'one'",
    ),
    "string power exponent": (
        GOOD.replace("p: linear", "p: power, p_params: {a: steep}"),
        r"filters\.0\.p_params\.a: must be a finite number > 0, got 'steep'",
    ),
    "NaN joint limits": (
        GOOD.replace("[1.0, 0.8]}", "[1.0, 0.8], limits: [[.nan, 1.0], [-3, 3]]}"),
        r"robot\.limits: must not be NaN",
    ),
    "3-D trajectory on a planar arm": (
        GOOD.replace(
            "{type: circle, centre: [1.2, 0.0], radius: 0.6, period: 10.0}",
            "{type: constant_velocity_line, begin: [1, 0, 0], end: [1.2, 0, 0], duration: 0.2}",
        ),
        r"trajectory: gives points of shape \(3,\) but planar2 has a position task of shape \(2,\)",
    ),
    "long value truncated": (
        GOOD.replace("loop_modes: [clik]", "loop_modes: [" + "x" * 5000 + "]"),
        r"loop_modes\.0.*\.\.\.",
    ),
    # item 5: per-controller shapes, found before compute
    "acceleration_limit length": (
        GOOD.replace(
            "backend: {type: pinv}",
            QP[:-1] + ", limits: [{type: acceleration, a_max: [1, 2, 3]}]}",
        ),
        r"controllers\.0 \(OTMM\)",
    ),
    "q_nominal length": (
        GOOD.replace(
            "backend: {type: pinv}", QP[:-1] + ", posture: {weight: 0.1, q_nominal: [1, 2, 3]}}"
        ),
        r"controllers\.0 \(OTMM\)",
    ),
    "2-D circle on a pose arm": (
        GOOD.replace(
            "{type: planar, link_lengths: [1.0, 0.8]}", "{type: pinocchio, name: ur5, task: pose}"
        ).replace("[0.927, -2.5]", "[0.0, -1.2, 1.5, -1.8, 0.3, 0.0]"),
        r"trajectory: gives points of shape \(2,\) but ur5 has a pose task",
    ),
    # item 9: step count
    "tiny dt": (GOOD.replace("dt: 0.02", "dt: 1.0e-9"), r"duration.*max_steps.*GiB"),
    "huge duration": (GOOD.replace("duration: 0.2", "duration: 1.0e+9"), r"duration.*GiB"),
    "max_steps key": (GOOD.replace("dt: 0.02", "dt: 0.02\nmax_steps: 5"), r"max_steps = 5"),
}


def _snapshot(folder: Path) -> dict[str, float]:
    """Every path under ``folder`` with its modification time."""
    return {str(p.relative_to(folder)): p.lstat().st_mtime for p in folder.rglob("*")}


@pytest.fixture
def sandbox(tmp_path: Path) -> Path:
    """A folder with an earlier run's results in ``earlier/`` (must survive every case)."""
    earlier = tmp_path / "earlier"
    earlier.mkdir()
    (earlier / "summary.csv").write_text("experiment,loop_mode,controller\nE,clik,c\n")
    return tmp_path


def _expect_refused(
    capsys: pytest.CaptureFixture[str], sandbox: Path, argv: list[str], pattern: str
) -> None:
    before = _snapshot(sandbox)
    status = main(argv)
    captured = capsys.readouterr()
    assert status == 2, captured.err
    text = refusal_text(captured.err)  # a first line of at most 200 characters, details after
    assert "Traceback" not in captured.out
    assert re.search(pattern, text), text
    after = _snapshot(sandbox)
    # nothing new except the config we wrote and (maybe) an empty --out; earlier results intact
    assert {k: v for k, v in before.items() if k in after} == before
    created = set(after) - set(before)
    assert all(not (sandbox / c).is_file() or c.endswith(".lock") for c in created), created


@pytest.mark.parametrize("case", sorted(CONFIG_CASES))
def test_bad_config_is_one_line_before_compute(
    case: str, sandbox: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    text, pattern = CONFIG_CASES[case]
    config = sandbox / "bad.yaml"
    if isinstance(text, bytes):
        config.write_bytes(text)
    else:
        config.write_text(text)
    out = sandbox / "out"
    _expect_refused(capsys, sandbox, ["run", str(config), "--out", str(out), "--quiet"], pattern)
    assert not (out / "summary.csv").exists()


def _file(sandbox: Path) -> str:
    (sandbox / "a_file").write_text("x")
    return str(sandbox / "a_file")


OUT_CASES: dict[str, tuple[Callable[[Path], str], str]] = {
    "empty": (lambda s: "", r"must not be empty"),
    "NUL": (lambda s: str(s / "a\x00b"), r"NUL"),
    "a file": (_file, r"exists and is not a directory"),
    "under /proc": (lambda s: "/proc/otmm-qp-results", r"cannot create a results folder"),
    "300-char name": (lambda s: str(s / ("x" * 300)), r"too long"),
    "earlier results": (lambda s: str(s / "earlier"), r"already holds results.*--force"),
}


@pytest.mark.parametrize("case", sorted(OUT_CASES))
def test_bad_out_is_refused_before_compute(
    case: str, sandbox: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    make, pattern = OUT_CASES[case]
    config = sandbox / "good.yaml"
    config.write_text(GOOD)
    out = make(sandbox)
    argv = ["run", str(config), "--out", out, "--quiet", "--figures", "none"]
    _expect_refused(capsys, sandbox, argv, pattern)


def test_max_steps_can_be_raised_explicitly(tmp_path: Path) -> None:
    config = tmp_path / "c.yaml"
    config.write_text(GOOD.replace("dt: 0.02", "dt: 0.02\nmax_steps: 5"))
    argv = ["run", str(config), "--out", str(tmp_path / "o"), "--quiet", "--figures", "none"]
    assert main(argv) == 2
    assert main([*argv, "--max-steps", "50"]) == 0


def test_suite_name_cannot_escape(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    work = tmp_path / "work"
    work.mkdir()
    monkeypatch.chdir(work)
    for name in ("../../escaped", "/tmp/otmm-escaped", "a\x00b", ".."):
        config = work / "c.yaml"
        config.write_text(GOOD.replace("name: tiny", f"name: {name!r}".replace("'", '"')))
        before = _snapshot(tmp_path)
        assert main(["run", str(config), "--quiet", "--figures", "none"]) == 0
        created = set(_snapshot(tmp_path)) - set(before)
        assert created and all(c.startswith("work/results") for c in created), created
    assert not Path("/tmp/otmm-escaped").exists()


def test_colliding_and_reserved_controller_names_keep_every_file(tmp_path: Path) -> None:
    names = ["a/b", "a?b", "a_b", "comparison", "summary"]
    block = "".join(f"      - name: {n!r}\n        backend: {{type: pinv}}\n" for n in names)
    text = GOOD.split("    controllers:")[0] + "    controllers:\n" + block
    config = tmp_path / "c.yaml"
    config.write_text(text)
    out = tmp_path / "out"
    assert main(["run", str(config), "--out", str(out), "--quiet", "--figures", "all"]) == 0
    folder = out / "A" / "clik"
    csvs = sorted(p.name for p in folder.glob("*.csv"))
    pngs = sorted(p.name for p in folder.glob("*.png"))
    assert len(csvs) == len(names)
    assert "comparison.png" in pngs and len(pngs) == len(names) + 1
    assert "comparison.csv" not in csvs


def _run_good(tmp_path: Path) -> Path:
    """Run the GOOD config into ``tmp_path/out`` (no figures); the results folder."""
    config = tmp_path / "c.yaml"
    config.write_text(GOOD)
    out = tmp_path / "out"
    assert main(["run", str(config), "--out", str(out), "--quiet", "--figures", "none"]) == 0
    return out


def test_reuse_needs_force_and_lock_blocks_concurrent_run(tmp_path: Path) -> None:
    import fcntl

    config = tmp_path / "c.yaml"
    config.write_text(GOOD)
    out = tmp_path / "out"
    argv = ["run", str(config), "--out", str(out), "--quiet", "--figures", "none"]
    assert main(argv) == 0
    stale = out / "A" / "clik" / "stale.png"
    stale.write_bytes(b"old figure")
    assert main(argv) == 2
    assert (out / "summary.csv").is_file()
    assert main([*argv, "--force"]) == 0
    assert not stale.exists()  # no silent mixing with the older run's figures
    with (out / ".otmm-qp.lock").open("w") as held:
        fcntl.flock(held, fcntl.LOCK_EX)
        assert main([*argv, "--force"]) == 2
    assert main([*argv, "--force"]) == 0


REPORT_CASES: dict[str, tuple[bytes, str]] = {
    "binary": (b"\x89PNG\x00\xff\xfe" * 50, r"not UTF-8"),
    "truncated": (b"experiment,loop_mode,contr", r"missing columns"),
    "no header": (b"", r"missing columns"),
}


@pytest.mark.parametrize("case", sorted(REPORT_CASES))
def test_report_on_damaged_folder_is_one_line(
    case: str, sandbox: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    data, pattern = REPORT_CASES[case]
    folder = sandbox / "damaged"
    folder.mkdir()
    (folder / "summary.csv").write_bytes(data)
    _expect_refused(capsys, sandbox, ["report", str(folder)], pattern)


def test_report_survives_nan_and_truncated_rows(tmp_path: Path) -> None:
    out = _run_good(tmp_path)
    summary = out / "summary.csv"
    header, row = summary.read_text().splitlines()[:2]
    cells = row.split(",")
    cells[5:9] = ["nan", "inf", "-inf", "garbage"]
    summary.write_text(header + "\n" + ",".join(cells) + "\nA,clik,cut-off-row\n")
    assert main(["report", str(out)]) == 0
    assert "cut-off-row" in (out / "report.md").read_text()


def test_report_never_follows_symlinks_out(tmp_path: Path) -> None:
    out = _run_good(tmp_path)
    secret = tmp_path / "secret.png"
    secret.write_bytes(b"SECRET-CONTENT")
    (out / "x.png").symlink_to(secret)
    (out / "linked").symlink_to(tmp_path)
    (out / "claims.md").symlink_to(tmp_path / "c.yaml")
    assert main(["report", str(out)]) == 2  # claims.md links outside: refused, one line
    (out / "claims.md").unlink()
    assert main(["report", str(out)]) == 0
    import base64

    html = (out / "report.html").read_text()
    assert base64.b64encode(b"SECRET-CONTENT").decode()[:12] not in html
    assert "x.png" not in html and "secret" not in html


def test_report_flags_relaxed_bounds(tmp_path: Path) -> None:
    out = _run_good(tmp_path)
    summary = out / "summary.csv"
    header, row = summary.read_text().splitlines()[:2]
    summary.write_text(f"{header},status_relaxed\n{row},7\n")
    assert main(["report", str(out)]) == 0
    assert "bound relaxed/infeasible on 7 steps" in (out / "report.md").read_text()


def test_report_on_read_only_folder(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """A folder the report cannot write to: exit 2, one line, the run's files untouched.

    Root ignores file modes, so the refusal is made where every write goes through
    (``tempfile.mkstemp`` in the atomic writer) as well as by the mode bits.
    """
    out = _run_good(tmp_path)
    summary_before = (out / "summary.csv").read_bytes()
    capsys.readouterr()

    def refuse(*args: object, **kwargs: object) -> tuple[int, str]:
        raise PermissionError(13, "Permission denied", str(out))

    monkeypatch.setattr(paths_module.tempfile, "mkstemp", refuse)
    out.chmod(0o555)
    try:
        assert main(["report", str(out)]) == 2
    finally:
        out.chmod(0o755)
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "Permission denied" in err[0] and "Traceback" not in err[0]
    assert (out / "summary.csv").read_bytes() == summary_before
    assert not list(out.glob(".*.tmp"))


def test_config_loop_modes_match_the_simulation() -> None:
    import typing

    from otmm_qp.config.schema import LoopMode
    from otmm_qp.simulation.loop_modes import LOOP_MODES

    assert typing.get_args(LoopMode) == LOOP_MODES


def test_unreachable_trajectory_is_typed(tmp_path: Path) -> None:
    from otmm_qp.config.load import load_config
    from otmm_qp.exceptions import ConfigError, UnreachableTrajectory
    from otmm_qp.runner.run import prepare_suite

    config = tmp_path / "c.yaml"
    config.write_text(GOOD.replace("radius: 0.6", "radius: 5.0"))
    with pytest.raises(UnreachableTrajectory, match="outside the workspace") as caught:
        prepare_suite(load_config(config))
    assert isinstance(caught.value, ConfigError)
    assert caught.value.field.endswith("experiments.0.trajectory")
