"""One path from config to CLI: every field of the prior, edit, online-run and algorithm configs
has its help beside it and is reachable from the command that uses the config, with that help."""

import dataclasses

import pytest
import typer
from typer.testing import CliRunner

from xted.cli.main import app
from xted.cli.options import config_options
from xted.diffusion.config import EditConfig, PriorConfig
from xted.fields import apply_overrides, field_help
from xted.rl.config import OFFLINE_ALGORITHMS, OnlineRunConfig, SACConfig

COMMANDS = typer.main.get_command(app)
EVERY_CONFIG = [EditConfig, PriorConfig, OnlineRunConfig, SACConfig, *OFFLINE_ALGORITHMS.values()]


def _command(path: str):
    command = COMMANDS
    for name in path.split():
        command = command.commands[name]
    return command


def _options(path: str) -> dict[str, str]:
    return {opt: param.help for param in _command(path).params for opt in param.opts}


@pytest.mark.parametrize("config_type", EVERY_CONFIG, ids=lambda c: c.__name__)
def test_every_field_has_help(config_type):
    assert all(field_help(config_type).values()), [k for k, v in field_help(config_type).items() if not v]


@pytest.mark.parametrize("path, config_type, not_options", [
    ("edit", EditConfig, ()),
    ("train", PriorConfig, ("state_dim", "action_dim")),
    ("online train", OnlineRunConfig, ("total_steps", "init_from", "sac", "td3")),
])
def test_each_field_is_an_option_with_its_help(path, config_type, not_options):
    options = _options(path)
    for name, text in field_help(config_type).items():
        if name in not_options:
            continue
        option = "--" + name.replace("_", "-")
        assert option in options, f"xted {path} has no {option}"
        assert options[option].startswith(text), (option, options[option])


def _sections(epilog: str) -> dict[str, list[str]]:
    """The epilog's field lines under each heading ("...:")."""
    sections: dict[str, list[str]] = {}
    for paragraph in epilog.split("\n\n"):
        if paragraph.endswith(":"):
            heading = sections.setdefault(paragraph, [])
        else:
            heading.append(paragraph)
    return sections


@pytest.mark.parametrize("path, configs", [
    ("policy", {name: ("", kind()) for name, kind in OFFLINE_ALGORITHMS.items()}),
    ("online train", {name: (f"{name}.", OnlineRunConfig()) for name in ("sac", "td3")}),
])
def test_set_fields_are_listed_with_their_help_and_parse(path, configs):
    sections = _sections(_command(path).epilog)
    for algo, (prefix, config) in configs.items():
        (lines,) = [lines for heading, lines in sections.items() if f"--algo {algo}" in heading]
        fields = getattr(config, prefix[:-1]) if prefix else config
        for field in dataclasses.fields(fields):
            if dataclasses.is_dataclass(getattr(fields, field.name)):
                continue
            listed = [line for line in lines if line.startswith(f"--set {prefix}{field.name}=")]
            assert listed and listed[0].endswith(field.metadata["help"]), (path, algo, field.name)
            pair = listed[0].split()[1]  # "field=default", the default as listed
            assert apply_overrides(config, [pair]) == config, pair


def test_derived_options_reach_the_config():
    seen = {}
    demo = typer.Typer()

    @demo.command()
    @config_options(EditConfig, into="fields")
    def run(name: str = typer.Option("x", "--name"), fields: list[str] = ()) -> None:
        seen["fields"], seen["name"] = fields, name

    @demo.command()
    @config_options(PriorConfig, into="fields", skip=("state_dim", "action_dim"), preset_defaults=True)
    def other(fields: list[str] = ()) -> None:
        seen["prior"] = fields

    runner = CliRunner()
    result = runner.invoke(demo, ["run", "--name", "y", "--target-return", "0.5", "--clip-denoised", "3",
                                  "--batch-size", "7", "--hold-actions"])
    assert result.exit_code == 0, result.output
    config = apply_overrides(EditConfig(), seen["fields"])
    assert seen["name"] == "y"
    assert (config.target_return, config.clip_denoised, config.batch_size, config.hold_actions) == (0.5, 3.0, 7, True)
    assert runner.invoke(demo, ["other", "--decay-steps", "none", "--no-use-reward", "--horizon", "8"]).exit_code == 0
    # Unset options stay unset (the preset decides); given ones, none included, are passed on.
    assert sorted(seen["prior"]) == ["decay_steps=none", "horizon=8", "use_reward=False"]


def test_a_field_named_like_a_command_option_is_refused():
    with pytest.raises(TypeError, match="kappa"):
        @config_options(EditConfig, into="fields")
        def clash(kappa: float = 0.0, fields: list[str] = ()) -> None:
            pass


def _command_paths(command=COMMANDS, path=()):
    yield path
    for name, sub in getattr(command, "commands", {}).items():
        yield from _command_paths(sub, (*path, name))


@pytest.mark.parametrize("path", list(_command_paths()), ids=" ".join)
def test_help_reads_as_plain_text(path):
    """No value hint on a flag (``--force <bool>`` reads as taking a value) and no reStructuredText
    markup leaking from docstrings into what a user reads."""
    result = CliRunner().invoke(app, [*path, "--help"], terminal_width=200)
    assert result.exit_code == 0, result.output
    assert "<bool>" not in result.output
    assert "``" not in result.output and ":func:" not in result.output


def test_one_default_for_offline_training_steps():
    import inspect

    from xted.api import train_policy
    from xted.pipelines.bench.config import BenchConfig
    from xted.rl.config import OFFLINE_STEPS

    assert _options("policy")["--steps"] is not None
    steps_option = next(p for p in _command("policy").params if p.name == "steps")
    assert steps_option.default == inspect.signature(train_policy).parameters["steps"].default == BenchConfig().steps
    assert BenchConfig().steps == OFFLINE_STEPS
