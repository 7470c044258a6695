"""The scene reference page, docs/scenes.md, is the generator's output from the schema."""

from __future__ import annotations

import dataclasses
import importlib.util
import re
import typing

import pydantic
from locations import ROOT
from scene_files import write_arm, write_cube_obj, write_cube_stl

from wander_env.scene_config import SceneConfig
from wander_env.scenes import load_scene_config

GENERATOR = ROOT / "docs" / "gen_scene_reference.py"


def _generator():
    spec = importlib.util.spec_from_file_location("gen_scene_reference", GENERATOR)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_committed_page_is_the_generators_output():
    page = (ROOT / "docs" / "scenes.md").read_text(encoding="utf-8")
    assert page == _generator().render(), "run: python docs/gen_scene_reference.py"


def _blocks() -> list[type]:
    """Every dataclass a scene document nests, SceneConfig first."""
    found: list[type] = []

    def visit(tp: typing.Any) -> None:
        if dataclasses.is_dataclass(tp) and isinstance(tp, type):
            if tp in found:
                return
            found.append(tp)
            for hint in typing.get_type_hints(tp).values():
                visit(hint)
        for arg in typing.get_args(tp):
            visit(arg)

    visit(SceneConfig)
    return found


def test_every_field_has_a_description_a_unit_and_a_row_on_the_page():
    schema = pydantic.TypeAdapter(SceneConfig).json_schema()
    page = (ROOT / "docs" / "scenes.md").read_text(encoding="utf-8")
    blocks = _blocks()
    assert len(blocks) == 19  # SceneConfig and the 18 blocks it nests
    rows = 0
    for cls in blocks:
        block = schema if cls is SceneConfig else schema["$defs"][cls.__name__]
        fields = [f.name for f in dataclasses.fields(cls) if f.init]
        assert list(block["properties"]) == fields, cls
        section = page.split(f": {cls.__name__}\n", 1)[1].split("\n## ", 1)[0]
        for name in fields:
            prop = block["properties"][name]
            assert prop.get("description"), (cls.__name__, name)
            assert "unit" in prop, (cls.__name__, name)
            row = re.search(rf"^\| `{name}` \|(.*)\|$", section, re.MULTILINE)
            assert row is not None, (cls.__name__, name)
            cells = [c.strip() for c in re.split(r"(?<!\\)\|", row.group(1))]
            assert cells[2] and cells[3] not in ("", "`null`"), (cls.__name__, name, cells)
            rows += 1
    assert rows == page.count("\n| `")


def test_the_pages_example_scene_validates(tmp_path):
    page = (ROOT / "docs" / "scenes.md").read_text(encoding="utf-8")
    example = page.split("```yaml\n", 1)[1].split("```", 1)[0]
    (tmp_path / "meshes").mkdir()
    (tmp_path / "robots").mkdir()
    write_cube_obj(tmp_path / "meshes" / "cup.obj")
    write_cube_stl(tmp_path / "meshes" / "bunny.stl")
    write_arm(tmp_path / "robots")
    (tmp_path / "my_scene.yaml").write_text(example)
    cfg = load_scene_config(tmp_path / "my_scene.yaml")
    assert [o.shape for o in cfg.static_objects] == ["box", "mesh"]
    assert cfg.moving_objects[0].mesh.file == str(tmp_path / "meshes" / "bunny.stl")
    assert cfg.mjcf_includes[0].name == "arm"


def test_the_generator_checks_and_writes(tmp_path, monkeypatch, capsys):
    gen = _generator()
    page = tmp_path / "scenes.md"
    monkeypatch.setattr(gen, "PAGE", page)
    assert gen.main(["gen", "--check"]) == 1
    assert gen.main(["gen"]) == 0
    assert gen.main(["gen", "--check"]) == 0
    assert page.read_text(encoding="utf-8") == gen.render()
    out = capsys.readouterr().out.splitlines()
    assert out == [
        f"{page}: differs; run docs/gen_scene_reference.py",
        f"wrote {page}",
        f"{page}: up to date",
    ]
