"""Dependencies point one way (issue 17 point 6): no import cycle between modules, the two
report modules independent, one safe-output module, one home for the paper's constants.

The import graph holds every first-party import: module level and inside every function body
(an import deferred into a function is still a dependency); only ``if TYPE_CHECKING:`` blocks
are left out (the ``python -m`` aliases that once called the CLI from below are retired, so no
import is excused). A planted function-level import that closes a cycle fails the test (checked
below)."""

from __future__ import annotations

import ast
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
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


def _all_imports(source: str) -> set[str]:
    """Every first-party import of ``source``, function bodies included (not TYPE_CHECKING)."""
    found: set[str] = set()

    def walk(node: ast.AST) -> None:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, ast.If) and "TYPE_CHECKING" in ast.unparse(child.test):
                for other in child.orelse:
                    walk(other)
                continue
            if isinstance(child, ast.ImportFrom) and (child.module or "").startswith("otmm_qp"):
                found.add(str(child.module))
                found.update(f"{child.module}.{a.name}" for a in child.names)
            elif isinstance(child, ast.Import):
                found.update(a.name for a in child.names if a.name.startswith("otmm_qp"))
            walk(child)

    walk(ast.parse(source))
    return found


def _graph(planted: dict[str, str] | None = None) -> dict[str, set[str]]:
    """Module → first-party modules it imports; ``planted`` appends source to modules."""
    files = {_module(p): p for p in PACKAGE.rglob("*.py")}
    graph = {}
    for module, path in files.items():
        source = path.read_text(encoding="utf-8") + (planted or {}).get(module, "")
        targets = {t for t in _all_imports(source) if t in files} - {module}
        graph[module] = targets
    return graph


def test_no_import_cycle_between_modules() -> None:
    _check_module_cycles(_graph())


def _check_module_cycles(graph: dict[str, set[str]]) -> None:
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
    study_report = {
        m
        for path in (PACKAGE / "studies" / "report").glob("*.py")
        for m in _imports(path, module_level=False)
    }
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


#: Leaf modules at the package root (they import only ``otmm_qp.exceptions`` and each other):
#: safe names and atomic writes, and the stop-signal path (backends hold SIGINT around native
#: solvers without the harness), are used from every layer.
LEAF_MODULES = {"otmm_qp.paths", "otmm_qp.interrupt"}

#: Upward imports left out of the package graph (none: the plants-study headline lives in
#: ``studies/`` and the trajectory that rebuilds a study task in ``scenarios/``).
KNOWN_UPWARD_IMPORTS: set[tuple[str, str]] = set()


def _package(module: str) -> str:
    """``otmm_qp.<package>`` of a module (a top-level module is its own node)."""
    return ".".join(module.split(".")[:2])


def _strongly_connected(graph: dict[str, set[str]]) -> list[set[str]]:
    """Tarjan's strongly connected components of ``graph`` with more than one node."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[set[str]] = []

    def visit(node: str) -> None:
        index[node] = low[node] = len(index)
        stack.append(node)
        on_stack.add(node)
        for target in sorted(graph.get(node, ())):
            if target not in index:
                visit(target)
                low[node] = min(low[node], low[target])
            elif target in on_stack:
                low[node] = min(low[node], index[target])
        if low[node] == index[node]:
            component = set()
            while True:
                member = stack.pop()
                on_stack.discard(member)
                component.add(member)
                if member == node:
                    break
            if len(component) > 1:
                found.append(component)

    for node in sorted(graph):
        if node not in index:
            visit(node)
    return found


def test_no_import_cycle_between_packages() -> None:
    """Imports grouped by package point one way (output → runner, never back)."""
    _check_package_cycles(_graph())


def _check_package_cycles(graph: dict[str, set[str]]) -> None:
    for leaf in LEAF_MODULES:
        assert leaf.count(".") == 1, f"{leaf} is a leaf: it belongs at the package root"
        allowed = ({"otmm_qp.exceptions"} | LEAF_MODULES) - {leaf}
        assert graph[leaf] <= allowed, f"{leaf} imports {sorted(graph[leaf])}"
    packages: dict[str, set[str]] = {}
    upward: set[tuple[str, str]] = set()
    for module, targets in graph.items():
        source = _package(module)
        for target in {_package(t) for t in targets} - {source}:
            if (module, target) in KNOWN_UPWARD_IMPORTS:
                upward.add((module, target))
                continue
            packages.setdefault(source, set()).add(target)
    assert upward == KNOWN_UPWARD_IMPORTS, (
        f"gone, delete from the list: {KNOWN_UPWARD_IMPORTS - upward}"
    )
    cycles = _strongly_connected(packages)
    assert not cycles, "package import cycles: " + "; ".join(
        " <-> ".join(sorted(c)) for c in cycles
    )


def test_the_runner_and_the_loop_never_import_the_results_layer() -> None:
    """``runner/`` hands runs to a ``RunSink``; ``output/run_writer.py`` writes them."""
    for package in ("runner", "simulation"):
        for path in (PACKAGE / package).glob("*.py"):
            upward = {
                m for m in _imports(path, module_level=False) if m.startswith("otmm_qp.output")
            }
            assert not upward, f"{path.relative_to(ROOT)} imports {sorted(upward)}"


def test_run_suite_takes_a_sink_not_a_path(tmp_path: Path) -> None:
    """A bare folder path (the old ``out_dir``) is refused in one line before any compute."""
    import pytest

    from otmm_qp.config.load import parse_config
    from otmm_qp.runner import run_suite

    experiment = {
        "name": "E",
        "robot": {"type": "planar", "link_lengths": [1.0, 0.8]},
        "q0": [0.0, 0.0],
        "trajectory": {"type": "quintic_line", "begin": [1.8, 0.0], "end": [0.6, -1.0]},
        "duration": 0.1,
        "controllers": [{"name": "pinv", "backend": {"type": "pinv"}}],
    }
    suite = parse_config({"name": "s", "loop_modes": ["clik"], "experiments": [experiment]})
    with pytest.raises(TypeError, match="out must be a RunSink such as .*ResultsWriter"):
        run_suite(suite, tmp_path, progress=None)  # type: ignore[arg-type]
    assert list(tmp_path.iterdir()) == []


def test_a_planted_function_level_import_closing_a_cycle_is_caught() -> None:
    """An import hidden in a function body still closes a cycle: both checks see it."""
    import pytest

    module_cycle = {
        "otmm_qp.studies.keys": "\n\ndef f():\n    from otmm_qp.studies.rows import load\n"
    }
    with pytest.raises(AssertionError, match="import cycle: .*otmm_qp.studies.keys"):
        _check_module_cycles(_graph(module_cycle))
    package_cycle = {"otmm_qp.metrics.table": "\n\ndef f():\n    import otmm_qp.studies.columns\n"}
    with pytest.raises(AssertionError, match="package import cycles: .*otmm_qp.metrics"):
        _check_package_cycles(_graph(package_cycle))
    typed = {
        "otmm_qp.studies.keys": "\nif TYPE_CHECKING:\n    from otmm_qp.studies.rows import load\n"
    }
    _check_module_cycles(_graph(typed))  # a type-only import is no dependency


def test_the_study_report_renders_only() -> None:
    """``studies/report/`` computes no statistics: the verdicts and summaries it renders are
    typed results of ``studies/verdicts.py``."""
    for path in (PACKAGE / "studies" / "report").glob("*.py"):
        imported = _all_imports(path.read_text(encoding="utf-8"))
        assert not {m for m in imported if m.startswith("otmm_qp.studies.statistics")}, path
