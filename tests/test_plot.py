"""xted plot: each command writes a readable PNG from tiny inputs; bad input exits 2 and writes nothing."""

import json

import numpy as np
import pytest
from conftest import first_steps
from PIL import Image

from xted.analysis import mean_spectra
from xted.cli.main import main
from xted.data import Dataset, save


def png_size(path) -> tuple[int, int]:
    with Image.open(path) as image:
        image.load()
        assert image.format == "PNG"
        return image.size


def with_observations(data: Dataset, observations: np.ndarray) -> Dataset:
    return Dataset(observations=observations, actions=data.actions, rewards=data.rewards, terminals=data.terminals,
                   timeouts=data.timeouts)


def test_mean_spectra_find_a_sine_and_its_change():
    steps = np.arange(200)
    source = first_steps("halfcheetah-thigh", 100)  # two episodes of 100 steps: 4 segments of 50
    wave = np.sin(2 * np.pi * 0.1 * steps)[:, None] * np.ones((1, source.observation_dim))
    noise = np.random.default_rng(0).normal(scale=0.01, size=wave.shape)
    source = with_observations(source, wave + noise)
    edited = with_observations(source, 2 * wave + noise)
    spectra = mean_spectra(source, edited, segment=50)
    assert spectra["segments"] == 4
    peak = int(np.argmax(spectra["source"][:, 0]))
    assert spectra["frequency"][peak] == pytest.approx(0.2)  # 0.1 cycles per step = 0.2 of Nyquist
    assert spectra["edited"][peak, 0] / spectra["source"][peak, 0] == pytest.approx(2.0, rel=0.05)


@pytest.fixture(scope="module")
def pair(tmp_path_factory):
    """Two 30-step halfcheetah episodes of the thigh source and a perturbed copy as its 'edit'."""
    folder = tmp_path_factory.mktemp("plot")
    source = first_steps("halfcheetah-thigh", 30)
    noise = np.random.default_rng(1).normal(scale=0.05, size=source.observations.shape)
    paths = str(folder / "source.npz"), str(folder / "edited.npz")
    save(source, paths[0])
    save(with_observations(source, source.observations + noise), paths[1])
    return paths


def test_spectrum_and_trajectory(pair, tmp_path):
    assert main(["plot", "spectrum", *pair, "--segment", "10", "--out", str(tmp_path / "s.png")]) == 0
    assert png_size(tmp_path / "s.png") == (1000, 400)
    assert main(["plot", "trajectory", *pair, "--env", "halfcheetah", "--episode", "1", "--dims", "0,8",
                 "--steps", "20", "--out", str(tmp_path / "t.png")]) == 0
    assert png_size(tmp_path / "t.png") == (900, 460)


EDIT_QUALITY_ROWS = [
    {"env": "halfcheetah", "gap": gap, "kappa": 0.5, "sim_source": s, "sim_edited": e, "proxy_source": s + 0.2,
     "proxy_edited": e + 0.1, "floor": {"sim": 0.3, "proxy": 0.35}}
    for gap, s, e in (("gravity", 0.2, 0.8), ("thigh", 1.1, 0.6))
]


def test_dynamics_from_edit_quality_rows(tmp_path):
    rows = tmp_path / "edit_quality.jsonl"
    rows.write_text("".join(json.dumps(row) + "\n" for row in EDIT_QUALITY_ROWS))
    assert main(["plot", "dynamics", str(rows), "--out", str(tmp_path / "d.png")]) == 0
    assert png_size(tmp_path / "d.png") == (760, 420)


def test_table_from_bench_rows(tmp_path):
    rows = [{"env": "halfcheetah", "target": "medium-replay", "gap": gap, "column": column, "algo": algo,
             "mean": m, "std": 0.8, "n_seeds": 3, "scores": [m - 1, m, m + 1]}
            for algo in ("iql", "td3bc") for gap in ("thigh", "gravity")
            for column, m in (("Tgt", 8.0), ("Tgt+Src", 5.0), ("Tgt+Edited", 6.0))]
    rows.append({**rows[0], "column": "Tgt+Oracle", "mean": None, "std": None, "n_seeds": 0, "scores": []})
    printed = tmp_path / "bench.json"
    printed.write_text(json.dumps({"rows": rows}))
    assert main(["plot", "table", str(printed), "--out", str(tmp_path / "table.png")]) == 0
    assert png_size(tmp_path / "table.png") == (760, 420)


def test_every_declared_column_drawn_at_once_gets_its_own_colour():
    from matplotlib.colors import to_rgb

    from xted.pipelines.bench.columns import COLUMNS
    from xted.viz.plots import column_colors

    colors = column_colors(list(COLUMNS))
    assert len({to_rgb(color) for color in colors.values()}) == len(COLUMNS)
    # a column keeps its colour whichever others are drawn beside it
    assert column_colors(["Tgt", "Tgt+Src OTDF"])["Tgt+Src OTDF"] == colors["Tgt+Src OTDF"]


def write_runs(folder):
    """A prior folder, an online run and an offline run, a few rows each."""
    (folder / "prior").mkdir()
    (folder / "prior" / "log.csv").write_text("step,loss,seconds\n100,0.9,1.0\n200,0.5,2.0\n300,0.4,3.0\n")
    (folder / "online").mkdir()
    (folder / "online" / "evals.csv").write_text(
        "step,return_mean,return_std,wall_seconds\n1000,-50.0,10.0,5.0\n2000,300.0,40.0,9.0\n")
    (folder / "offline").mkdir()
    for seed in (0, 1):
        evals = [{"step": step, "normalized_score": 10.0 * step / 1000 + seed, "return_mean": 0.0}
                 for step in (1000, 2000)]
        (folder / "offline" / f"seed_{seed}.json").write_text(json.dumps({"seed": seed, "evals": evals}))


def test_curves_of_each_kind_of_run(tmp_path):
    write_runs(tmp_path)
    for kind in ("prior", "online", "offline"):
        out = tmp_path / f"{kind}.png"
        assert main(["plot", "curves", str(tmp_path / kind), "--out", str(out)]) == 0, kind
        assert png_size(out) == (750, 420)
    assert main(["plot", "curves", str(tmp_path / "online" / "evals.csv"), str(tmp_path / "online"),
                 "--out", str(tmp_path / "two.png")]) == 0


@pytest.mark.parametrize("command, message", [
    (["dynamics", "{tmp}/missing.jsonl", "--out", "{tmp}/out.png"], "no such file"),
    (["dynamics", "{tmp}/rows.jsonl", "--out", "{tmp}/out.jpg"], "written as .png"),
    (["table", "{tmp}/rows.jsonl", "--out", "{tmp}/out.png"], "not the output of xted bench"),
    (["dynamics", "{tmp}/broken.jsonl", "--out", "{tmp}/out.png"], "broken.jsonl:2: not a JSON object"),
    (["curves", "{tmp}", "--out", "{tmp}/out.png"], "found none of them"),
    (["curves", "{tmp}/runs/prior", "{tmp}/runs/online", "--out", "{tmp}/out.png"], "runs of one kind"),
    (["trajectory", "{tmp}/rows.jsonl", "{tmp}/rows.jsonl", "--env", "halfcheetah", "--out", "{tmp}/out.png"],
     "rows.jsonl"),
])
def test_bad_input_exits_2_and_writes_no_png(tmp_path, capsys, command, message):
    (tmp_path / "rows.jsonl").write_text(json.dumps(EDIT_QUALITY_ROWS[0]) + "\n")
    (tmp_path / "broken.jsonl").write_text(json.dumps(EDIT_QUALITY_ROWS[0]) + "\n{not json\n")
    (tmp_path / "runs").mkdir()
    write_runs(tmp_path / "runs")
    before = sorted(tmp_path.rglob("*"))
    assert main(["plot", *[part.replace("{tmp}", str(tmp_path)) for part in command]]) == 2
    assert message in capsys.readouterr().err
    assert sorted(tmp_path.rglob("*")) == before


@pytest.mark.parametrize("reference, closer", [(1, 17), (0, 0)])
def test_spectrum_beside_a_target(pair, tmp_path, capsys, reference, closer):
    """With the edit itself as the target every dim of the edit is closer to it; with the source, none."""
    assert main(["plot", "spectrum", *pair, "--segment", "10", "--target", pair[reference],
                 "--out", str(tmp_path / "s.png")]) == 0
    assert f"closer to the target in {closer} of 17 state dims" in capsys.readouterr().out
    assert png_size(tmp_path / "s.png") == (1000, 400)
