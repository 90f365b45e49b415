"""Install ``examples/otmm_qp_example_plugin`` into a folder the way pip would register it.

A ``*.dist-info`` with the ``entry_points.txt`` pip would write (read from the example's own
``pyproject.toml``) plus the package source on the path: ``importlib.metadata`` then finds
the plugin exactly as for an installed distribution, with no network or build step.
"""

from __future__ import annotations

from pathlib import Path

import tomllib

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "otmm_qp_example_plugin"


def install_example_plugin(target: Path) -> list[Path]:
    """Write the dist-info into ``target``; return the folders to put on ``sys.path``."""
    project = tomllib.loads((EXAMPLE / "pyproject.toml").read_text())["project"]
    info = target / f"{project['name'].replace('-', '_')}-{project['version']}.dist-info"
    info.mkdir(parents=True, exist_ok=True)
    (info / "METADATA").write_text(
        f"Metadata-Version: 2.1\nName: {project['name']}\nVersion: {project['version']}\n"
    )
    lines = []
    for group, entries in project["entry-points"].items():
        lines.append(f"[{group}]")
        lines += [f"{name} = {value}" for name, value in entries.items()]
    (info / "entry_points.txt").write_text("\n".join(lines) + "\n")
    return [target, EXAMPLE / "src"]
