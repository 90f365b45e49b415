"""Every command the README names is mapped to the test that runs it.

Extraction (``readme_commands``), on the README's raw text:

1. **Fenced ``bash`` blocks:** every non-empty line, with backslash continuations joined and a
   trailing comment (``  # …``) removed; a comment of the form ``# or: COMMAND`` adds COMMAND.
2. **Inline code spans** outside fenced blocks (a span may wrap over one line break) that start
   with ``otmm-qp`` followed by a space or the span's end (so the message ``otmm-qp: error: …``
   is not a command), or with ``python``, ``pytest`` or ``.venv/bin/…`` followed by an argument.
3. **A config path joined to a command:** in "`` `otmm-qp run A.yaml` and `B.yaml` ``", B is
   run by the same command, so ``otmm-qp run B.yaml`` is added.

Each command is normalised by collapsing whitespace. ``COMMANDS`` maps each normalised command
to the tests (``path::function``) that run it and a note saying where the test's run differs
(reduced counts, figures, the executor) or why the command itself is not run in the suite. The
test fails when the README names a command ``COMMANDS`` lacks, when an entry is no longer in the
README, or when an entry names a test function that does not exist (found with ``ast``).
"""

from __future__ import annotations

import ast
import re
from functools import cache
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]

_RUNS = "tests/docs/test_readme_runs.py"
_STRATEGIES_TABLE = f"{_RUNS}::test_readme_strategies_table_is_regenerated"
_PLANAR_NUMBERS = (
    "tests/docs/test_readme_numbers.py::test_planar_study_table_in_readme_is_regenerated"
)
_RUN_REPORT = "tests/commands/test_commands.py::test_run_then_report"
_CI = (
    "tests/architecture/test_packaging.py::"
    "test_ci_runs_lint_format_and_types_before_the_readme_test_command"
)
_OWN_ARM = "tests/docs/test_your_own_arm.py::test_doc_steps_take_a_urdf_package_to_a_verdict"

# command (normalised) → (tests that run it, how their run differs / why not run as is)
COMMANDS: dict[str, tuple[tuple[str, ...], str]] = {
    "python3 -m venv .venv && .venv/bin/pip install -q . && .venv/bin/otmm-qp": (
        (
            "tests/docs/test_readme_paper_numbers.py::"
            "test_bare_command_reproduces_the_paper_into_results_paper",
        ),
        "installing is not run in the suite; the bare otmm-qp runs as `run` into results/paper "
        "with --figures none (comparison figures: the strategies fixture)",
    ),
    'python3 -m venv .venv && .venv/bin/pip install -q ".[test,peers]" && .venv/bin/pytest': (
        (_CI,),
        "the suite itself; the test checks it is the command .ci/run runs",
    ),
    "otmm-qp study configs/studies/planar.yaml --out results/planar-study": (
        (_PLANAR_NUMBERS,),
        "into tmp_path, --workers 1 (results do not depend on the executor)",
    ),
    "otmm-qp study configs/studies/arms.yaml --out results/arms-study": (
        (f"{_RUNS}::test_arms_study_command_reduced",),
        "20,000 episodes (~6 min): the shipped file with every count set to 1, --workers 1",
    ),
    "otmm-qp study FILE --workers 1": ((_PLANAR_NUMBERS,), ""),
    "otmm-qp study FILE --scheduler tcp://HOST:8786": (
        (
            "tests/studies/test_studies.py::test_external_scheduler_with_a_worker_killed_midway",
            "tests/studies/test_studies.py::test_unreachable_scheduler_fails_fast",
        ),
        "a real `dask scheduler` on 127.0.0.1 with two workers",
    ),
    "otmm-qp report results/planar-study": (
        (f"{_RUNS}::test_arms_study_command_reduced",),
        "`report` on a study folder (the reduced arms study)",
    ),
    "otmm-qp study configs/studies/strategies_readme.yaml --out results/strategies-readme "
    "--highlight sigma_lm": (
        ("tests/docs/test_readme_strategies.py::test_readme_strategies_table_is_regenerated",),
        "not re-run by the suite: its stored rows (tests/data/strategies_readme, the file's study "
        "id) are what tools/doc_tables.py --check renders",
    ),
    "otmm-qp init study --urdf my_jaco_description/robots/kinova.urdf --package-dir . "
    "--frame j2s6s200_end_effector --locked-joints j2s6s200_joint_finger_1 "
    "j2s6s200_joint_finger_2 -o jaco-study.yaml": (
        (_OWN_ARM,),
        "verbatim, in a folder holding a copy of example-robot-data's Jaco as a user's package",
    ),
    "otmm-qp study jaco-study.yaml --out results/jaco-study": (
        (_OWN_ARM,),
        "--workers 1, every generator's count 1 and decide {budget_tasks: 6, batch: 6}",
    ),
    "otmm-qp study verdict results/jaco-study --ours qp --kinds": (
        (_OWN_ARM,),
        "verbatim, on the study above",
    ),
    "otmm-qp study verdict results/strategies-readme --ours sigma_lm --kinds": (
        ("tests/docs/test_readme_strategies.py::test_readme_strategies_table_is_regenerated",),
        "with --out, on the stored rows of the study above (tools/doc_tables.py --check)",
    ),
    "otmm-qp study configs/studies/strategies_arms.yaml --out results/strategies-arms "
    "--workers 1": (
        ("tests/studies/test_tradeoff.py::test_the_command_prints_the_table",),
        "a tiny planar study in tmp_path stands for the 2,112-episode arms study (~70 s)",
    ),
    "otmm-qp study tradeoff results/strategies-arms --group-by kind": (
        ("tests/studies/test_tradeoff.py::test_the_command_prints_the_table",),
        "both groupings on the tiny study; the README's counts come from the "
        "full study (docs/strategies.md gives the command and timings)",
    ),
    "otmm-qp study configs/studies/preview_crossings_ur5.yaml --out results/preview-crossings-ur5 "
    "--workers 1": (
        (
            "tests/controllers/preview/test_backend.py::test_the_per_arm_crossing_studies_judge_one_preview_row",
            "tests/controllers/preview/test_backend.py::test_study_rows_record_their_information_class",
        ),
        "the shipped file is planned (840 episodes: 84 tasks x (9 rows + the reference)) and a "
        "tiny planar study with preview rows runs in tmp_path; the README's numbers come from "
        "the full file (~9 min with --workers 1; docs/strategies.md)",
    ),
    "otmm-qp study verdict results/preview-crossings-ur5 --ours preview-minmax --kinds": (
        (
            "tests/controllers/preview/test_backend.py::test_study_rows_record_their_information_class",
        ),
        "the verdict with --kinds on the tiny preview study",
    ),
    "otmm-qp study configs/studies/plants.yaml --out results/plants-study": (
        ("tests/plants/test_plant_runs.py::test_shipped_plants_study_plans_and_runs_a_slice",),
        "1,000 episodes (~1 min): a slice of the shipped file; the README's plant table is not "
        "regenerated by the suite (the command below prints it)",
    ),
    "otmm-qp study plants results/plants-study": (
        ("tests/plants/test_plant_runs.py::test_plants_axis_names_rows_and_keeps_old_keys",),
        "on a small plants study",
    ),
    "pytest --otmm-controller my_backend [--otmm-params '{\"gain\": 2}'] "
    '[--otmm-filters \'[{"type": "otmm", "p": "linear"}]\'] '
    "[--otmm-scenarios paper/E1,paper/E3]": (
        (
            "tests/testing/test_pytest_plugin.py::test_example_plugin_passes_the_suite",
            "tests/testing/test_pytest_plugin.py::test_pinv_fails_bounded_speed_at_the_singular_start",
        ),
        "a pytest subprocess with the example plugin and pinv",
    ),
    "otmm-qp bench --out results/bench --steps 300": (
        ("tests/commands/test_commands.py::test_bench_subcommand",),
        "--steps 10 (timings are not asserted)",
    ),
    "python benchmarks/bench_step.py": (
        ("tests/commands/test_commands.py::test_bench_step_script",),
        "",
    ),
    "python benchmarks/bench_qp_session.py": (
        ("tests/bench/test_qp_bench.py::test_bench_qp_session_prints_every_row",),
        "reduced size",
    ),
    "python benchmarks/bench_strategies.py": (
        ("tests/commands/test_commands.py::test_bench_strategies_runs_tiny",),
        "reduced size",
    ),
    "python benchmarks/bench_study.py --tasks 64": (
        ("tests/studies/test_shipped.py::test_bench_study_runs_tiny",),
        "fewer tasks",
    ),
    '.venv/bin/pip install -e ".[test,lint]"': (
        (_CI,),
        "installing is not run in the suite; .ci/run installs the same extras",
    ),
    ".venv/bin/ruff check . && .venv/bin/ruff format --check . && .venv/bin/mypy": (
        (_CI,),
        "lint, not a test: the test checks .ci/run runs exactly these before pytest",
    ),
    "otmm-qp run FILE [--out DIR] [--force] [--max-steps N]": (
        (
            _RUN_REPORT,
            "tests/hostile/test_folders.py::"
            "test_folder_kinds_are_never_mixed_and_force_replaces_the_earlier_kind",
            "tests/hostile/test_input.py::test_max_steps_can_be_raised_explicitly",
        ),
        "",
    ),
    "otmm-qp list": (("tests/commands/test_commands.py::test_list_names_every_group",), ""),
    "otmm-qp migrate FILE [-o OUT]": (
        (
            "tests/migration/test_versions.py::test_migrate_cli_prints_what_it_changed",
            "tests/migration/test_versions.py::test_shipped_run_config_runs_identically_after_migrate",
        ),
        "",
    ),
    "otmm-qp report DIR": ((_RUN_REPORT,), ""),
    "otmm-qp study show DIR --episode ID": (
        ("tests/studies/test_report.py::test_show_writes_a_config_that_reproduces_the_episode",),
        "",
    ),
    "otmm-qp study configs/studies/planar.yaml --workers 2": (
        (_PLANAR_NUMBERS, "tests/studies/test_studies.py::test_local_cluster_gives_identical_rows"),
        "the shipped file runs with --workers 1; LocalCluster(2) is checked to give identical rows",
    ),
    "otmm-qp study configs/studies/arms.yaml --out /tmp/arms-study": (
        (f"{_RUNS}::test_arms_study_command_reduced",),
        "as results/arms-study above",
    ),
    "otmm-qp run configs/strategies/paper.yaml": (
        (_STRATEGIES_TABLE,),
        "--figures comparison (the per-run PNGs: tests/output/test_figures.py)",
    ),
    "otmm-qp run configs/strategies/arms.yaml": ((_STRATEGIES_TABLE,), "--figures none"),
    "otmm-qp run configs/arms/ur5_wrist.yaml --replay": (
        (f"{_RUNS}::test_ur5_wrist_replay_command",),
        "--figures none",
    ),
    "otmm-qp replay RESULTS_DIR [--experiment E --controller C]": (
        (
            "tests/replay/test_replay.py::test_planar_gif_frames_and_the_drawn_tip_follow_the_stored_path",
        ),
        "",
    ),
    "otmm-qp report RESULTS_DIR": ((_RUN_REPORT,), ""),
}

_COMMAND_START = re.compile(r"otmm-qp(\s|$)|(python3?|pytest|\.venv/bin/\S+)\s")


def _normalise(command: str) -> str:
    return " ".join(command.split())


def readme_commands(text: str) -> list[str]:
    """The commands ``text`` (a README) names, normalised, in order, without repeats."""
    found: list[str] = []
    for block in re.findall(r"^```bash\n(.*?)^```", text, flags=re.S | re.M):
        for line in block.replace("\\\n", " ").splitlines():
            alternative = re.search(r"#\s*or:\s*(.+)$", line)
            if alternative:
                found.append(alternative.group(1))
            line = re.sub(r"(^|\s)#\s.*$", "", line)
            if line.strip():
                found.append(line)
    prose = re.sub(r"^```.*?^```", "", text, flags=re.S | re.M)
    for span in re.findall(r"`([^`]+?)`", prose):
        if "\n\n" not in span and _COMMAND_START.match(span):
            found.append(span)
    joined = re.findall(r"`(otmm-qp \w+) [^`\s]+\.yaml` and `([^`\s]+\.yaml)`", prose)
    found.extend(f"{verb} {path}" for verb, path in joined)
    return list(dict.fromkeys(_normalise(c) for c in found))


@cache
def _test_functions(path: str) -> frozenset[str]:
    tree = ast.parse((ROOT / path).read_text(encoding="utf-8"))
    return frozenset(
        node.name
        for node in ast.walk(tree)
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef) and node.name.startswith("test")
    )


# The pages the README's long evidence moved to: a mapped command may be named there instead.
EVIDENCE_PAGES = (
    "docs/studies.md",
    "docs/study-results.md",
    "docs/strategies.md",
    "benchmarks/PERFORMANCE.md",
)


def test_every_readme_command_is_mapped_to_a_test() -> None:
    commands = readme_commands((ROOT / "README.md").read_text(encoding="utf-8"))
    unmapped = [c for c in commands if c not in COMMANDS]
    assert not unmapped, f"README commands with no entry in COMMANDS: {unmapped}"
    named = set(commands)
    for page in EVIDENCE_PAGES:
        named.update(readme_commands((ROOT / page).read_text(encoding="utf-8")))
    stale = [c for c in COMMANDS if c not in named]
    assert not stale, f"COMMANDS entries neither the README nor its evidence pages name: {stale}"


def test_every_mapped_test_exists() -> None:
    missing = []
    for command, (tests, _note) in COMMANDS.items():
        assert tests, f"{command}: names no test"
        for test in tests:
            path, _, function = test.partition("::")
            if not (ROOT / path).is_file() or function not in _test_functions(path):
                missing.append((command, test))
    assert not missing, f"mapped tests that do not exist: {missing}"


def test_extraction_rules() -> None:
    """The three rules, and the spans that are not commands."""
    text = (
        "```bash\n"
        "otmm-qp run a.yaml --out x   # a comment\n"
        "pytest --flag \\\n       --other\n"
        "otmm-qp bench     # or: python b.py\n"
        "```\n"
        "Run `otmm-qp study c.yaml --out\nd` or `otmm-qp run e.yaml` and `f.yaml`; "
        "errors read `otmm-qp: error: FIELD`, files `configs/g.yaml`, words `python`.\n"
    )
    assert readme_commands(text) == [
        "otmm-qp run a.yaml --out x",
        "pytest --flag --other",
        "python b.py",
        "otmm-qp bench",
        "otmm-qp study c.yaml --out d",
        "otmm-qp run e.yaml",
        "otmm-qp run f.yaml",
    ]


def _plan_sizes(name: str) -> tuple[int, int, int]:
    """(episodes, tasks, controller rows after grid expansion) of a shipped study's plan."""
    from otmm_qp.studies.spec import load_study, plan_study

    episodes = plan_study(load_study(ROOT / "configs" / "studies" / f"{name}.yaml")).episodes
    tasks = {(e.robot, e.generator, e.task_index) for e in episodes}
    controllers = {e.controller for e in episodes if not e.is_reference}  # the oracle: none
    return len(episodes), len(tasks), len(controllers)


def test_study_sizes_the_readme_states_are_the_plans() -> None:
    """The sizes written next to the study commands, from the shipped files' plans (no runs).

    The plants results moved to docs/plants.md and the planar and arms study results to
    docs/study-results.md: their sentences are checked there.
    """
    sources = ("README.md", "docs/plants.md", "docs/study-results.md")
    text = " ".join(" ".join((ROOT / s).read_text(encoding="utf-8").split()) for s in sources)
    (p_episodes, p_tasks, p_rows), (a_episodes, a_tasks, a_rows), (l_episodes, l_tasks, l_rows) = (
        _plan_sizes(n) for n in ("planar", "arms", "plants")
    )
    checks = [
        (r"planar\.yaml --out results/planar-study # (\d+) episodes \((\d+) of them oracle rows\)",
         (p_episodes, p_tasks)),
        (r"\((\d+) tasks × (\d+) controllers \+ one oracle row per task", (p_tasks, p_rows)),
        (r"UR5 \+ Panda, ([\d,]+) tasks x \((\d+) controllers \+ oracle\)", (a_tasks, a_rows)),
        (r"([\d,]+) UR5 \+ Panda pose tasks × (\d+) controllers \+ one reference per task, "
         r"([\d,]+) episodes", (a_tasks, a_rows, a_episodes)),
        (r"plants\.yaml --out results/plants-study # (\d+) episodes", (l_episodes,)),
        (r"The same (\d+) UR5 and Panda pose tasks .*? under eighteen plants: (\d+) controller "
         r"episodes plus one offline reference per task", (l_tasks, l_tasks * l_rows)),
    ]  # fmt: skip
    for pattern, expected in checks:
        found = re.search(pattern, text)
        assert found, f"the sentence changed its form: {pattern}"
        assert tuple(int(g.replace(",", "")) for g in found.groups()) == expected, pattern
    # docs/studies.md states the same sizes next to its copies of the commands
    studies = " ".join((ROOT / "docs" / "studies.md").read_text(encoding="utf-8").split())
    for pattern, expected in (
        (r"planar\.yaml --out results/planar-study # < 1 min, (\d+) episodes", (p_episodes,)),
        (r"arms\.yaml --out results/arms-study # UR5 \+ Panda, ([\d,]+) episodes", (a_episodes,)),
    ):
        found = re.search(pattern, studies)
        assert found, f"docs/studies.md changed its form: {pattern}"
        assert tuple(int(g.replace(",", "")) for g in found.groups()) == expected, pattern


def test_the_readme_opens_with_the_two_commands_then_its_contents() -> None:
    """A newcomer's page: the two set-up commands first, a table of contents, under 20 KB."""
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    first_block = text.split("```bash\n", 1)[1].split("```", 1)[0].strip().splitlines()
    assert first_block == [
        "python3 -m venv .venv && .venv/bin/pip install -q . && .venv/bin/otmm-qp",
        'python3 -m venv .venv && .venv/bin/pip install -q ".[test,peers]" && .venv/bin/pytest',
    ]
    contents = text.index("\n## Contents")
    assert contents == text.index("\n## ")  # the first section after the commands
    headings = re.findall(r"^## (.+)$", text, flags=re.M)
    linked = re.findall(r"^- \[(.+?)\]\(#", text[contents:], flags=re.M)
    assert linked == [h for h in headings if h != "Contents"]
    assert len(text.encode("utf-8")) < 20 * 1024
