"""Every Python package of the source tree is listed in pyproject.toml (a wheel install has it)."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
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
