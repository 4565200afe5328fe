"""A result as a researcher looks at it: a short repr, a Jupyter table, pandas and xarray views,
save and load; a model's one-screen repr."""
from __future__ import annotations

import numpy as np
import pytest

import grasping_sym as gs


@pytest.fixture(scope="module")
def result(paper2d_model):
    return paper2d_model.simulate(0.5, method="radau", rtol=1e-6, atol=1e-8)


def test_repr_is_one_line_and_html_a_table(result):
    text = repr(result)
    assert "\n" not in text and len(text) < 300
    assert "radau" in text and "501 samples" in text and "steps" in text
    page = result._repr_html_()
    assert page.count("<tr>") == 1 + len(result.state_names) + len(result.outputs)
    f = result["f"]
    assert f"<td>{f[-1]:.6g}</td>" in page and f"<td>{np.min(f):.6g}</td>" in page


def test_dataframe_and_xarray_hold_the_same_numbers(result):
    df = result.to_dataframe()
    assert list(df.columns) == [*result.state_names, *result.outputs]
    assert np.array_equal(df.index.values, result.t) and np.array_equal(df["q1"].values, result["q1"])
    ds = result.to_xarray()
    assert np.array_equal(ds["f"].values, result["f"]) and np.array_equal(ds["t"].values, result.t)
    assert ds.attrs["method"] == "radau"


def test_save_and_load_round_trip_and_refuse_other_files(result, tmp_path):
    path = result.save(tmp_path / "run")
    assert path.suffix == ".npz"
    back = gs.SimulationResult.load(path)
    assert np.array_equal(back.x, result.x) and np.array_equal(back.t, result.t)
    assert back.state_names == result.state_names and back.method == result.method
    assert all(np.array_equal(back.outputs[k], v) for k, v in result.outputs.items())
    assert back.stats["n_steps"] == result.stats["n_steps"]
    other = tmp_path / "other.npz"
    np.savez(other, t=result.t)
    with pytest.raises(ValueError, match="not a saved SimulationResult"):
        gs.SimulationResult.load(other)
    pickled = tmp_path / "pickled.npz"
    np.savez(pickled, meta=np.array([{"format": "x"}], dtype=object))
    with pytest.raises(ValueError, match="pickle"):
        gs.SimulationResult.load(pickled)


def test_model_repr_fits_a_screen(paper2d_model):
    text = repr(paper2d_model)
    lines = text.splitlines()
    assert len(lines) <= 12 and all(len(line) <= 110 for line in lines)
    assert lines[0].startswith("Model 'paper2d': 7 states")
    assert "controller  paper" in text and "start       xm = " in text
