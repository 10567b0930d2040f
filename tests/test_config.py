import dataclasses

import pytest

from xted.fields import apply_overrides
from xted.errors import InputError


@dataclasses.dataclass(frozen=True)
class Inner:
    rate: float = 0.1


@dataclasses.dataclass(frozen=True)
class Example:
    flag: bool = False
    width: int = 4
    scale: float | None = 1.0
    hidden: tuple[int, ...] = (8, 8)
    inner: Inner = Inner()

    def __post_init__(self):
        if self.width < 1:
            raise InputError(f"width must be >= 1, got {self.width}")


@pytest.mark.parametrize("text, value", [("true", True), ("1", True), ("Yes", True), ("false", False), ("0", False),
                                         ("no", False)])
def test_boolean_overrides_accept_the_usual_words(text, value):
    assert apply_overrides(Example(), [f"flag={text}"]).flag is value


@pytest.mark.parametrize("pair", ["flag=tru", "flag=", "flag=2", "width=four", "scale=big", "depth=3", "width",
                                  "hidden=8,x", "hidden=0", "inner=3", "inner.speed=2"])
def test_bad_overrides_name_the_pair(pair):
    with pytest.raises(InputError, match="--set"):
        apply_overrides(Example(), [pair])


def test_typed_values_widths_nested_and_none():
    config = apply_overrides(Example(), ["width=8", "scale=none", "hidden=64,32", "inner.rate=0.5"])
    assert config == Example(width=8, scale=None, hidden=(64, 32), inner=Inner(0.5))


def test_the_config_validates_the_result():
    with pytest.raises(InputError, match="width must be >= 1"):
        apply_overrides(Example(), ["width=0"])


def test_rl_configs_validate_themselves():
    from xted.rl.bc import BCConfig
    from xted.rl.dara import DARAConfig
    from xted.rl.iql import IQLConfig
    from xted.rl.sac import SACConfig
    from xted.rl.td3bc import TD3BCConfig

    for config in (BCConfig(), DARAConfig(), IQLConfig(), SACConfig(), TD3BCConfig()):
        assert dataclasses.replace(config) == config
    bad = [(IQLConfig, {"discount": 1.5}, "IQLConfig.discount"), (IQLConfig, {"expectile": 0.0}, "expectile"),
           (TD3BCConfig, {"hidden": ()}, "TD3BCConfig.hidden"), (SACConfig, {"learning_rate": 0.0}, "learning_rate"),
           (DARAConfig, {"classifier_steps": 0}, "classifier_steps"), (BCConfig, {"batch_size": 2.5}, "batch_size"),
           (TD3BCConfig, {"policy_noise": -0.1}, "policy_noise")]
    for kind, fields, needle in bad:
        with pytest.raises(InputError, match=needle):
            kind(**fields)


def test_negative_seeds_are_refused_by_the_configs_the_cli_options_come_from():
    from xted.diffusion.config import EditConfig, preset
    from xted.rl.config import OnlineRunConfig

    for build in (lambda: EditConfig(seed=-1), lambda: preset("tiny", 3, 2, seed=-1), lambda: OnlineRunConfig(seed=-1)):
        with pytest.raises(InputError, match="seed"):
            build()
