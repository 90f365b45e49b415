"""Dependencies point one way (issue 17 point 6): no import cycle between modules, the two
report modules independent, one safe-output module, one home for the paper's constants."""

from __future__ import annotations

import ast
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "otmm_qp"


def _module(path: Path) -> str:
    parts = path.relative_to(ROOT).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _imports(path: Path, *, module_level: bool) -> set[str]:
    tree = ast.parse(path.read_text(encoding="utf-8"))
    nodes = tree.body if module_level else list(ast.walk(tree))
    found: set[str] = set()
    for node in nodes:
        if isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("otmm_qp"):
            found.add(node.module)
            found.update(f"{node.module}.{a.name}" for a in node.names)
        elif isinstance(node, ast.Import):
            found.update(a.name for a in node.names if a.name.startswith("otmm_qp"))
    return found


def _graph() -> dict[str, set[str]]:
    files = {_module(p): p for p in PACKAGE.rglob("*.py")}
    return {
        m: {t for t in _imports(p, module_level=True) if t in files} - {m} for m, p in files.items()
    }


def test_no_import_cycle_between_modules() -> None:
    graph = _graph()
    state: dict[str, int] = {}
    stack: list[str] = []

    def visit(node: str) -> None:
        state[node] = 1
        stack.append(node)
        for target in sorted(graph.get(node, ())):
            if target.startswith(node + "."):
                continue  # a package importing its own submodules
            if state.get(target) == 1:
                cycle = stack[stack.index(target) :] + [target]
                raise AssertionError("import cycle: " + " -> ".join(cycle))
            if target not in state:
                visit(target)
        stack.pop()
        state[node] = 2

    for node in sorted(graph):
        if node not in state:
            visit(node)


def test_run_report_and_study_report_do_not_import_each_other() -> None:
    run_report = _imports(PACKAGE / "output" / "report.py", module_level=False)
    study_report = _imports(PACKAGE / "studies" / "report.py", module_level=False)
    assert not any(m.startswith("otmm_qp.studies") for m in run_report)
    assert not any(m.startswith("otmm_qp.output.report") for m in study_report)


def test_config_and_simulation_do_not_import_runner_studies_or_reports() -> None:
    for package in ("config", "simulation", "metrics"):
        for path in (PACKAGE / package).glob("*.py"):
            upward = {
                m for m in _imports(path, module_level=False)
                if m.startswith(("otmm_qp.runner", "otmm_qp.studies", "otmm_qp.commands",
                                 "otmm_qp.output.report", "otmm_qp.replay"))
            }  # fmt: skip
            assert not upward, f"{path.relative_to(ROOT)} imports {sorted(upward)}"


def test_one_safe_output_module_and_one_home_for_sigma_s() -> None:
    assert not (PACKAGE / "replay" / "safe_output.py").exists()
    literal = re.compile(r"(?i)sigma_s\w*\s*(?::\s*float\s*)?=\s*(?:Field\()?0\.05\b")
    offenders = [
        str(p.relative_to(ROOT))
        for p in PACKAGE.rglob("*.py")
        if p.name != "paper.py" and literal.search(p.read_text(encoding="utf-8"))
    ]
    assert offenders == []
    from otmm_qp.filters.otmm import DEFAULT_SIGMA_S
    from otmm_qp.metrics import MetricSettings
    from otmm_qp.paper import SIGMA_S

    assert DEFAULT_SIGMA_S == MetricSettings().sigma_s == SIGMA_S == 0.05


def test_the_core_never_imports_the_built_in_backends() -> None:
    """Built-in backends live in ``controllers/`` and reach the core only through entry points,
    exactly as a third party's do; ``otmm_qp/backends/`` holds the interface alone."""
    offenders = {
        str(p.relative_to(ROOT)): sorted(
            m for m in _imports(p, module_level=False) if m.startswith("otmm_qp_controllers")
        )
        for p in PACKAGE.rglob("*.py")
    }
    assert {k: v for k, v in offenders.items() if v} == {}
    assert sorted(p.name for p in (PACKAGE / "backends").glob("*.py")) == [
        "__init__.py",
        "backend.py",
    ]
    assert not (PACKAGE / "peers").exists()


def test_controllers_import_each_other_relatively() -> None:
    """Inside ``controllers/`` imports are relative, so mypy checks the package as one unit
    (an absolute ``otmm_qp_controllers`` import is unresolvable under an editable install)."""
    absolute = [
        str(p.relative_to(ROOT))
        for p in (ROOT / "controllers").rglob("*.py")
        if any(m.startswith("otmm_qp_controllers") for m in _imports(p, module_level=False))
    ]
    assert absolute == []


def test_replay_reads_run_folders_only_through_results_dir() -> None:
    """No replay module parses a CSV or names a run-folder file (issue 17 point 5)."""
    for path in (PACKAGE / "replay").glob("*.py"):
        tree = ast.parse(path.read_text(encoding="utf-8"))
        modules = {a.name for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names}
        modules |= {n.module for n in ast.walk(tree) if isinstance(n, ast.ImportFrom) if n.module}
        assert "csv" not in modules, f"{path.relative_to(ROOT)} imports csv"
        strings = {
            n.value
            for n in ast.walk(tree)
            if isinstance(n, ast.Constant) and isinstance(n.value, str)
        }
        named = {s for s in strings if s in {"summary.csv", "robot.json", "*/*/*.csv"}}
        assert not named, f"{path.relative_to(ROOT)} names the layout: {sorted(named)}"
