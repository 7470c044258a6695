"""The one config system (wander_env.config): nested blocks, overrides, messages."""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import pytest

from agents.attention import AgentParams
from agents.soms import SOMSParams
from experiments.studies.framework import resolve_config
from wander_env.config import ConfigError, check_fields, parse_sets, validate


@dataclass(frozen=True)
class Block:
    alpha: float = 0.8
    k: int = 8


@dataclass(frozen=True)
class Outer:
    name: str = "x"
    block: Block = field(default_factory=Block)
    soms: SOMSParams = field(default_factory=SOMSParams)

    def __post_init__(self) -> None:
        if self.block.k < 1:
            raise ValueError(f"block.k must be >= 1, got {self.block.k}")


def test_an_old_flat_key_is_an_unknown_key_naming_the_allowed_ones():
    """The alias layer is gone: a former flat key (``alpha`` for ``soms.alpha``) is an
    unknown key, named with the block's keys."""
    with pytest.raises(ConfigError) as e:
        validate(Outer, {"alpha": 0.5}, where="c.yaml")
    assert str(e.value).startswith("c.yaml: unknown key 'alpha' for Outer; allowed keys: ")
    assert "soms (SOMSParams)" in str(e.value)


def test_nested_set_changes_only_the_named_field():
    base = Outer(block=Block(alpha=0.5, k=3))
    cfg = validate(Outer, parse_sets(["soms.alpha=0.6", "block.k=4"], Outer), base, "--set")
    assert cfg.soms.alpha == 0.6 and cfg.soms.sigma_s == SOMSParams().sigma_s
    assert cfg.block == Block(alpha=0.5, k=4)  # alpha kept from base
    assert isinstance(cfg.soms, SOMSParams) and cfg.name == "x"


def test_dotted_keys_of_a_mapping_are_nested_too():
    cfg = validate(Outer, {"soms.tau_mem": 0.05, "block": {"alpha": 1}})
    assert cfg.soms.tau_mem == 0.05 and cfg.block.alpha == 1.0


def test_a_real_parameter_block_validates_nested():
    p = validate(AgentParams, parse_sets(["soms.alpha=0.6", "window_s=0.05"], AgentParams))
    assert p.soms.alpha == 0.6 and p.window_s == 0.05
    assert p.soms.norm == AgentParams().soms.norm  # the rest of the agent's sOMS kept


def test_bad_nested_key_names_its_path_and_the_blocks_allowed_keys():
    with pytest.raises(ConfigError) as e:
        validate(Outer, parse_sets(["soms.alph=0.6"], Outer), where="--set")
    msg = str(e.value)
    assert msg.startswith("--set: soms: unknown key 'alph' for SOMSParams; allowed keys: ")
    assert "alpha (float)" in msg and "sigma_c (float)" in msg


def test_bad_nested_value_names_path_type_and_value():
    with pytest.raises(ConfigError) as e:
        validate(Outer, {"block": {"k": 1.5}}, where="c.yaml")
    assert str(e.value) == "c.yaml: block.k: expected int, got 1.5"
    with pytest.raises(ConfigError, match=r"c\.yaml: block.alpha: "):
        validate(Outer, {"block": {"alpha": True}}, where="c.yaml")
    with pytest.raises(ConfigError, match=r"^--set: block.k must be >= 1, got 0$"):
        validate(Outer, {"block": {"k": 0}}, where="--set")
    with pytest.raises(ConfigError, match=r"^x: soms.alpha: alpha must be in \[0, 1\], got -1.0$"):
        validate(Outer, {"soms": {"alpha": -1.0}}, where="x")


def test_yaml_file_error_names_the_file_the_field_and_the_value(tmp_path):
    from experiments.studies.framework import get_experiment

    path = tmp_path / "det.yaml"
    path.write_text("scenes: [office, 3]\n")
    with pytest.raises(ConfigError) as e:
        resolve_config(get_experiment("detection"), path)
    msg = str(e.value)
    assert msg == f"{path}: scenes[1]: expected str, got 3"


def test_a_key_given_twice_is_refused_not_the_last_one_kept(tmp_path):
    from experiments.studies.framework import get_experiment

    path = tmp_path / "det.yaml"
    path.write_text("repeats: 1\nagent:\n  soms: {alpha: 0.5}\nrepeats: 3\n")
    with pytest.raises(ConfigError) as e:
        resolve_config(get_experiment("detection"), path)
    assert str(e.value) == f"{path}: line 4, column 1: duplicate key 'repeats'"


@pytest.mark.parametrize("text", ["017", "0x10", "0b11", "1:20", "1_000", "-017", "1:20.5"])
def test_yaml_11_number_forms_that_read_as_other_values_are_refused(text):
    """PyYAML reads ``017`` as 15 and ``1:20`` as 80: nothing silently cast."""
    with pytest.raises(ConfigError) as e:
        parse_sets([f"block.k={text}"], Outer)
    assert str(e.value) == (
        f"--set block.k: line 1, column 1: {text!r}: write numbers in plain decimal (YAML 1.1 "
        "reads this form as octal, hexadecimal, binary or base 60)"
    )
    assert parse_sets(["block.k=0", "block.alpha=017.5"], Outer) == {
        "block": {"k": 0, "alpha": 17.5}
    }


@pytest.mark.parametrize("value", ["5e-1", "0.5", ".5"])
def test_a_front_end_field_written_as_a_numeric_string_is_read_as_the_number(tmp_path, value):
    """``5e-1`` is a string to YAML 1.1; in the tagged union of ``agent.soms`` it is read
    as the float it writes, as it is elsewhere."""
    from experiments.studies.framework import get_experiment

    cfg = resolve_config(get_experiment("detection"), sets=[f"agent.soms.alpha={value}"])
    assert cfg.agent.soms.alpha == 0.5
    path = tmp_path / "c.yaml"
    path.write_text(f"agent:\n  soms:\n    alpha: {value}\n")
    assert resolve_config(get_experiment("detection"), path).agent.soms.alpha == 0.5


def test_set_cannot_set_a_block_and_one_of_its_keys():
    with pytest.raises(ConfigError, match="block is set to a value already"):
        parse_sets(["block=1", "block.k=2"], Outer)


def test_check_fields_names_class_field_bound_and_value():
    @dataclass
    class P:
        a: float = 1.0
        n: int = 2

        def __post_init__(self) -> None:
            check_fields(self, ("a",), positive=True)
            check_fields(self, ("n",), integer=True, minimum=1)

    for kwargs, text in [
        ({"a": 0.0}, "P.a must be a finite number > 0, got 0.0"),
        ({"a": float("nan")}, "P.a must be a finite number > 0, got nan"),
        ({"a": True}, "P.a must be a finite number > 0, got True"),
        ({"n": 0}, "P.n must be an int >= 1, got 0"),
        ({"n": 2.0}, "P.n must be an int >= 1, got 2.0"),
    ]:
        with pytest.raises(ValueError) as e:
            P(**kwargs)
        assert str(e.value) == text
    assert P(a=0.5, n=3).n == 3


def test_a_nested_block_is_laid_over_the_fields_default_not_its_class_defaults():
    """``agent.soms.alpha`` over the benchmark's config changes alpha alone: the block under
    it stays the field's default (the paper-literal sOMS: min-max norm, direct filters),
    not ``AgentParams``' own default sOMS (the agent's quantile norm)."""
    from experiments.benchmark.model import ModelConfig
    from wander_env.config import validate

    got = validate(ModelConfig, {"agent": {"soms": {"alpha": 0.5}}}).agent.soms
    assert (got.alpha, got.norm, got.conv) == (0.5, "minmax", "direct")
    assert got == replace(ModelConfig().agent.soms, alpha=0.5)
