"""A user's URDF package: every mesh it names lies inside its package, and exists when found.

A URDF names meshes as ``package://PKG/rel`` URIs (found under ``DIR/PKG/rel`` for a
``DIR`` of ``package_dirs``), as paths relative to the URDF file, or as absolute paths. A
mesh path that leaves its package (``package://arm/../../etc/x.stl``, ``../../x.stl`` past
the package root) is refused whatever the directories, and so is a mesh that no package
directory holds when ``package_dirs`` are given (the user said where the meshes are). Without
``package_dirs`` unresolved ``package://`` meshes are left alone: the kinematics need none.

The package root of a relative path is the nearest folder above the URDF holding a
``package.xml`` (a ROS package), else the URDF's folder's parent (``PKG/urdf/arm.urdf``).
"""

from __future__ import annotations

import os
import xml.etree.ElementTree as ElementTree
from collections.abc import Iterator, Sequence

from otmm_qp.exceptions import RobotLoadError

__all__ = ["check_meshes", "mesh_filenames", "package_root"]


def mesh_filenames(urdf_path: str) -> Iterator[str]:
    """Every ``<mesh filename=...>`` of a URDF file, in document order (unparsable: none)."""
    try:
        root = ElementTree.parse(urdf_path).getroot()
    except (ElementTree.ParseError, OSError):
        return  # the URDF parser reports it
    for mesh in root.iter("mesh"):
        filename = mesh.get("filename")
        if filename:
            yield filename


def package_root(urdf_path: str) -> str:
    """The folder a URDF's relative mesh paths must stay in (see the module docstring)."""
    folder = os.path.dirname(os.path.abspath(urdf_path))
    probe = folder
    while True:
        if os.path.isfile(os.path.join(probe, "package.xml")):
            return probe
        parent = os.path.dirname(probe)
        if parent == probe:
            return os.path.dirname(folder)
        probe = parent


def _inside(path: str, folder: str) -> bool:
    folder = os.path.normpath(folder)
    return os.path.commonpath([os.path.normpath(path), folder]) == folder


def check_meshes(urdf_path: str, package_dirs: Sequence[str]) -> None:
    """Refuse a mesh path outside its package, or not found under the given ``package_dirs``.

    Args:
        urdf_path: The URDF file.
        package_dirs: Folders holding packages (``DIR/PKG/...``); may be empty.

    Raises:
        RobotLoadError: ``urdf: mesh 'URI' ...`` naming the first offending mesh.
    """
    root = package_root(urdf_path)
    for filename in mesh_filenames(urdf_path):
        if filename.startswith("package://"):
            relative = filename.removeprefix("package://")
            package = relative.split("/", 1)[0]
            if not package or package in (".", ".."):
                raise RobotLoadError(f"urdf: mesh {filename!r} names no package")
            if not _inside(os.path.join("/", relative), os.path.join("/", package)):
                raise RobotLoadError(
                    f"urdf: mesh {filename!r} lies outside its package {package!r}"
                )
            if package_dirs and not any(
                os.path.isfile(os.path.join(str(d), relative)) for d in package_dirs
            ):
                raise RobotLoadError(
                    f"urdf: mesh {filename!r} not found under package_dirs "
                    f"({', '.join(map(str, package_dirs))}; each must hold {package}/)"
                )
            continue
        path = filename.removeprefix("file://")
        if os.path.isabs(path):
            continue  # the user's own absolute path: left to the tools that read meshes
        resolved = os.path.join(os.path.dirname(os.path.abspath(urdf_path)), path)
        if not _inside(resolved, root):
            raise RobotLoadError(f"urdf: mesh {filename!r} lies outside the package {root}")
        if not os.path.isfile(resolved):
            raise RobotLoadError(f"urdf: mesh {filename!r} not found ({resolved})")
