"""Safe output names and atomic writes (otmm_qp.paths)."""

from __future__ import annotations

import os
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from otmm_qp.exceptions import OtmmError, OutputPathError
from otmm_qp.paths import (
    UniqueNames,
    atomic_open,
    atomic_write_bytes,
    atomic_write_text,
    ensure_inside,
    safe_name,
)

SAFE_CHARS = set("ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789._-")


@pytest.mark.parametrize(
    ("name", "expected"),
    [
        ("qp", "qp"),
        ("otmm+qp", "otmm_qp"),
        ("a/b", "ab"),
        ("a?b", "a_b"),
        ("..", "_"),
        (".", "_"),
        ("", "_"),
        ("\x00", "_"),
        ("../../escaped", "escaped"),
        ("/etc/passwd", "etcpasswd"),
        (".hidden", "hidden"),
        ("-rf", "rf"),
        ("__", "__"),
    ],
)
def test_safe_name_examples(name: str, expected: str) -> None:
    assert safe_name(name) == expected


@settings(max_examples=200, deadline=None)
@given(st.text())
def test_safe_name_is_always_one_plain_component(name: str) -> None:
    slug = safe_name(name)
    assert 1 <= len(slug) <= 64
    assert set(slug) <= SAFE_CHARS
    assert slug not in (".", "..")
    assert not slug.startswith((".", "-"))


def test_long_names_stay_distinct_and_bounded() -> None:
    a, b = "x" * 300 + "a", "x" * 300 + "b"
    assert safe_name(a) != safe_name(b)
    assert len(safe_name(a)) == 64
    assert safe_name(a) == safe_name(a)


def test_unique_names_resolves_collisions_and_reserved() -> None:
    names = UniqueNames()
    assert names.get("a/b") == "ab"
    assert names.get("a?b") == "a_b"
    assert names.get("a_b") == "a_b-2"
    assert names.get("a?b") == "a_b"  # same name -> same slug
    assert names.get("comparison") == "comparison-2"
    assert names.get("Summary") == "Summary-2"
    assert UniqueNames(reserved=()).get("report") == "report"


def test_ensure_inside(tmp_path: Path) -> None:
    root = tmp_path / "out"
    root.mkdir()
    assert ensure_inside(root, root / "a" / "b.csv") == (root / "a" / "b.csv").resolve()
    with pytest.raises(OutputPathError, match="outside the results folder"):
        ensure_inside(root, root / ".." / "x.csv")
    (root / "link").symlink_to("/etc")
    with pytest.raises(OutputPathError):
        ensure_inside(root, root / "link" / "passwd")
    assert issubclass(OutputPathError, OtmmError)


def test_atomic_write_replaces_whole_file(tmp_path: Path) -> None:
    target = tmp_path / "a.csv"
    atomic_write_text(target, "old\n")
    atomic_write_bytes(tmp_path / "b.bin", b"\x00\x01")
    assert (tmp_path / "b.bin").read_bytes() == b"\x00\x01"
    with pytest.raises(RuntimeError), atomic_open(target) as handle:
        handle.write("half")
        raise RuntimeError("interrupted")
    assert target.read_text() == "old\n"
    assert sorted(os.listdir(tmp_path)) == ["a.csv", "b.bin"]  # no temp file left
    atomic_write_text(target, "new\n")
    assert target.read_text() == "new\n"
