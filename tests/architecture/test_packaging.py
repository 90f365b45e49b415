"""Every Python package of the source tree is listed in pyproject.toml (a wheel install has it)."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
# package-dir of pyproject.toml: import name -> folder
FOLDERS = {"otmm_qp": "otmm_qp", "otmm_qp_controllers": "controllers", "otmm_qp_configs": "configs"}


def test_every_subpackage_is_packaged() -> None:
    text = (ROOT / "pyproject.toml").read_text(encoding="utf-8")  # tomllib needs Python 3.11
    block = re.search(r"^packages = \[(.*?)\]", text, flags=re.S | re.M)
    assert block is not None
    listed = set(re.findall(r'"([\w.]+)"', block.group(1)))
    for name, folder in FOLDERS.items():
        assert f'"{name}" = "{folder}"' in text
        for init in (ROOT / folder).rglob("__init__.py"):
            relative = init.parent.relative_to(ROOT / folder)
            package = ".".join((name, *relative.parts))
            assert package in listed, f"{package} is missing from [tool.setuptools] packages"


def test_version_is_declared_once_in_pyproject() -> None:
    from importlib import metadata

    import tomllib

    import otmm_qp

    root = Path(__file__).resolve().parents[2]
    declared = tomllib.loads((root / "pyproject.toml").read_text())["project"]["version"]
    assert otmm_qp.__version__ == metadata.version("otmm-qp") == declared
    assert declared not in (root / "otmm_qp" / "__init__.py").read_text()


def test_ci_runs_lint_format_and_types_before_the_readme_test_command() -> None:
    import tomllib

    root = Path(__file__).resolve().parents[2]
    steps = [
        line.strip()
        for line in (root / ".ci" / "run").read_text().splitlines()
        if line.strip().startswith(".venv/bin/")
    ]
    assert steps == [
        ".venv/bin/ruff check .",
        ".venv/bin/ruff format --check .",
        ".venv/bin/mypy",
        ".venv/bin/pytest --junitxml=.ci-first-pass.xml",  # the README's command, times kept
        ".venv/bin/pytest -p randomly -q $FAST",  # again, re-shuffled, on the fastest files
    ]
    # pytest-randomly (test extra) shuffles both passes; the second takes the fastest files
    extra = tomllib.loads((root / "pyproject.toml").read_text())["project"]["optional-dependencies"]
    assert any(spec.startswith("pytest-randomly") for spec in extra["test"])
    assert "fast_subset.py .ci-first-pass.xml --budget 60" in (root / ".ci" / "run").read_text()
    install = next(
        line for line in (root / ".ci" / "run").read_text().splitlines() if "pip install" in line
    )
    assert '".[test,peers,lint]"' in install
    # the README's test command is what CI runs (with the lint extra added)
    readme = (root / "README.md").read_text()
    assert '.venv/bin/pip install -q ".[test,peers]" && .venv/bin/pytest' in readme
