"""Documentation that must follow the code: the generated scene reference, and the keys of the
public scene format."""

from __future__ import annotations

import dataclasses
import importlib.util
import re
import tomllib
import types
import typing
from pathlib import Path

import pytest

from rodnet import config, scene

ROOT = Path(__file__).resolve().parents[1]
SCRIPT = ROOT / "docs" / "make_scene_reference.py"


def _generator():
    """docs/ is not a package: load the generator by file path."""
    spec = importlib.util.spec_from_file_location("make_scene_reference", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_every_scene_key_has_a_description() -> None:
    gen = _generator()
    assert gen.missing_descriptions() == [], (
        "add these keys to DESCRIPTIONS in docs/make_scene_reference.py")
    assert gen.stale_descriptions() == [], (
        "these DESCRIPTIONS name no key of rodnet.config; remove or rename them")


def test_scene_reference_is_up_to_date() -> None:
    committed = (ROOT / "docs" / "scene_reference.md").read_text()
    assert _generator().render() == committed, (
        "docs/scene_reference.md is out of date: run `python docs/make_scene_reference.py`")


def _scene_format() -> Path | None:
    """SCENE_FORMAT.md: beside the repository in ``shared/``, or inside it."""
    for candidate in (ROOT.parent / "shared" / "SCENE_FORMAT.md", ROOT / "SCENE_FORMAT.md",
                      ROOT / "docs" / "SCENE_FORMAT.md"):
        if candidate.is_file():
            return candidate
    return None


def _format_keys(text: str) -> dict[str, set[str]]:
    """Section name -> keys named in the TOML blocks of SCENE_FORMAT.md.

    Keys are those of the parsed TOML plus optional keys written in comments as ``key = ...``
    or ``key [unit]`` (``# axial_stiffness = EA [N]``, ``# or shear_modulus = ...``).
    """
    found: dict[str, set[str]] = {}
    for block in re.findall(r"```toml\n(.*?)```", text, flags=re.S):
        section = None
        for line in block.splitlines():
            header = re.match(r"\s*\[\[?([a-z_]+)\]\]?", line)
            if header:
                section = header.group(1)
                found.setdefault(section, set())
            if "#" in line and section is not None:
                comment = line.split("#", 1)[1]
                found[section].update(re.findall(r"\b([a-z]+(?:_[a-z]+)+) (?:= |\[)", comment))
        for section, value in tomllib.loads(block).items():
            tables = value if isinstance(value, list) else [value]
            for table in tables:
                found.setdefault(section, set()).update(table)
    return found


def test_scene_format_keys_exist_in_config() -> None:
    path = _scene_format()
    if path is None:
        pytest.skip("SCENE_FORMAT.md not found (looked in ../shared, ., docs/)")
    hints = typing.get_type_hints(config.Scene)
    checked = 0
    for section, keys in _format_keys(path.read_text()).items():
        if section in scene.NOT_YET:  # refused by this version with a clear error
            continue
        assert section in scene.TABLES or section in scene.ARRAYS, (
            f"SCENE_FORMAT.md section [{section}] is neither parsed nor refused")
        hint = hints[section]
        args = [a for a in typing.get_args(hint) if a is not type(None) and a is not Ellipsis]
        cls = args[0] if typing.get_origin(hint) in (tuple, typing.Union, types.UnionType) else hint
        fields = {f.name for f in dataclasses.fields(cls)}
        missing = sorted(keys - fields)
        assert not missing, f"[{section}] keys of SCENE_FORMAT.md missing in rodnet.config: {missing}"
        checked += len(keys)
    assert checked > 50  # the blocks were found and parsed
