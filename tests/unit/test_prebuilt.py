"""The native binaries compiled at install time: taken when the sources are theirs, else zig."""

from __future__ import annotations

from pathlib import Path

import pytest

from papwc.errors import BuildError
from papwc.fmubuild import native_build, prebuilt
from papwc.fmubuild.native_build import TARGETS, ZIG_VERSION, zig_command
from papwc.fmubuild.prebuilt import DIGEST_FILE, sources_digest, take


def _tree(tmp_path: Path, text: str = "int x;\n") -> Path:
    tree = tmp_path / "fmu"
    (tree / "sources").mkdir(parents=True)
    (tree / "sources" / "model.c").write_text(text)
    return tree


def _installed(native_dir: Path, tree: Path, name: str = "M") -> dict[str, bytes]:
    """Binaries of model ``name`` installed for ``tree``'s sources; their bytes by platform."""
    files = {}
    for folder, (_targets, suffix, _extra) in TARGETS.items():
        path = native_dir / name / folder / f"{name}{suffix}"
        path.parent.mkdir(parents=True)
        path.write_bytes(folder.encode() * 3)
        files[folder] = path.read_bytes()
    (native_dir / name / DIGEST_FILE).write_text(sources_digest(tree) + "\n")
    return files


def test_binaries_of_the_same_sources_are_taken(tmp_path: Path) -> None:
    tree = _tree(tmp_path)
    files = _installed(tmp_path / "native", tree)
    assert take(tree, "M", tmp_path / "native")
    for folder, (_targets, suffix, _extra) in TARGETS.items():
        assert (tree / "binaries" / folder / f"M{suffix}").read_bytes() == files[folder]


def test_binaries_of_other_sources_are_not_taken(tmp_path: Path) -> None:
    _installed(tmp_path / "native", _tree(tmp_path / "old"))
    changed = _tree(tmp_path / "new", "int x = 1;\n")
    assert not take(changed, "M", tmp_path / "native")
    assert not (changed / "binaries").exists()
    assert not take(changed, "Other", tmp_path / "native")  # none installed for that model


def test_a_missing_platform_is_not_taken(tmp_path: Path) -> None:
    tree = _tree(tmp_path)
    _installed(tmp_path / "native", tree)
    next((tmp_path / "native" / "M" / "win64").iterdir()).unlink()
    assert not take(tree, "M", tmp_path / "native")


@pytest.mark.parametrize("found, said", [
    (None, "zig is not installed"),
    ("0.13.0", "ziglang 0.13.0 is installed, which compiles other bytes"),
])
def test_compiling_without_the_pinned_zig_is_refused_in_one_line(monkeypatch, found, said):
    monkeypatch.setattr(native_build, "zig_version", lambda: found)
    with pytest.raises(BuildError) as info:
        zig_command()
    message = str(info.value)
    assert "\n" not in message
    assert said in message and f"pip install 'ziglang=={ZIG_VERSION}'" in message


def test_the_installed_binaries_live_in_the_package() -> None:
    assert prebuilt.NATIVE_DIR == Path(native_build.__file__).resolve().parents[1] / "_native"
