"""A result as a researcher looks at it: a short repr, a Jupyter table, pandas and xarray views,
save and load (an edited file refused by name); a model's one-screen repr."""
from __future__ import annotations

import io
import json
import zipfile

import numpy as np
import pytest

import grasping_sym as gs
from grasping_sym.errors import InvalidResultError, ResultFileError


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
    with pytest.raises(ResultFileError, match="not a saved SimulationResult"):
        gs.SimulationResult.load(other)
    pickled = tmp_path / "pickled.npz"
    np.savez(pickled, meta=np.array([{"format": "x"}], dtype=object))
    with pytest.raises(ResultFileError, match="pickle"):
        gs.SimulationResult.load(pickled)


def _meta(change):
    def edit(entries):
        meta = json.loads(str(entries["meta"]))
        change(meta)
        entries["meta"] = np.array(json.dumps(meta))
    return edit


@pytest.mark.parametrize("edit, match", [
    (lambda e: e.update(x=e["x"][:, :3]), r"x has shape \(501, 3\), but there are 501 times and 7 "
                                          r"state names"),
    (lambda e: e.update(t=e["t"][:7]), r"x has shape \(501, 7\), but there are 7 times"),
    (lambda e: e.update(output_1=e["output_1"][:-1]), r"output '\w+' has shape \(500,\), but there "
                                                      "are 501 times"),
    (lambda e: e["t"].__setitem__(3, np.nan), "'t' holds 1 non-finite times"),
    (lambda e: e["t"].__setitem__(3, 0.0), "'t' is not strictly increasing"),
    (lambda e: e.update(x=e["x"].astype(str)), "'x' holds <U32 values, not numbers"),
    (lambda e: e.pop("output_2"), r"the entries \['output_2'\] are missing"),
    (lambda e: e.update(output_99=e["t"]), r"the entries \['output_99'\] are not listed"),
    (lambda e: e.update(meta=np.array(json.dumps([1, 2]))), "'meta' is a JSON list, not an object"),
    (lambda e: e.update(meta=np.arange(3)), r"'meta' is an array of shape \(3,\)"),
    (_meta(lambda m: m.pop("state_names")), r"'meta' lacks \['state_names'\]"),
    (_meta(lambda m: m.update(state_names=m["state_names"][:3])), "x has shape .* 3 state names"),
    (_meta(lambda m: m.update(outputs=["Q", "Q", "f"])), r"'outputs' names \['Q'\] more than once"),
    (_meta(lambda m: m.update(method=["radau"])), "'method' = \\['radau'\\] is not a string"),
    (_meta(lambda m: m.update(params={"fd": "x"})), r"'params' \['fd'\] are not finite numbers"),
    (_meta(lambda m: m.update(params={"fd": float("nan")})), r"'params' \['fd'\] are not finite"),
    (_meta(lambda m: m.update(stats=[])), "'stats' is a JSON list"),
])
def test_an_edited_file_is_refused_naming_the_file_and_the_entry(result, tmp_path, edit, match):
    """A shared .npz changed by hand: every entry checked against the others before use."""
    path = result.save(tmp_path / "bad.npz")
    with np.load(path) as f:
        entries = {k: f[k].copy() for k in f.files}
    assert len(result.outputs) >= 3
    edit(entries)
    np.savez(path, **entries)
    with pytest.raises(ResultFileError, match=match) as err:
        gs.SimulationResult.load(path)
    assert str(path) in str(err.value)


def test_a_file_built_to_exhaust_the_reader_is_refused(result, tmp_path):
    """meta nested 100 000 deep (json's recursion) and an entry whose header declares 50 TiB
    over 64 bytes of data (numpy would allocate before reading): named, nothing allocated."""
    path = result.save(tmp_path / "deep.npz")
    with np.load(path) as f:
        entries = {k: f[k].copy() for k in f.files}
    np.savez(path, **{**entries, "meta": np.array("[" * 100_000 + "]" * 100_000)})
    with pytest.raises(ResultFileError, match="deep.npz"):
        gs.SimulationResult.load(path)
    huge = tmp_path / "huge.npz"
    np.savez(huge, **entries)
    header = io.BytesIO()
    np.lib.format.write_array_header_1_0(header, {"descr": "<f8", "fortran_order": False,
                                                  "shape": (10**12, 7)})
    with zipfile.ZipFile(huge, "a") as z:
        z.writestr("x_big.npy", header.getvalue() + bytes(64))
    with pytest.raises(ResultFileError, match=r"'x_big' declares shape \(1000000000000, 7\)"):
        gs.SimulationResult.load(huge)


def test_drawing_options_and_the_scene_are_checked_first(result, tmp_path):
    """A misspelt option, or a scene whose states are not the result's: named before any
    drawing (nothing written)."""
    from grasping_sym.errors import ViewOptionError

    with pytest.raises(ViewOptionError, match=r"animate: unknown option\(s\) \['fsp'\]; the options are"):
        gs.viz.animate(result, tmp_path / "a.gif", fsp=3)
    with pytest.raises(ViewOptionError, match=r"view: unknown option\(s\) \['title'\]"):
        gs.viz.view(result, tmp_path / "v.html", gs.scenes.paper3d(), title="x")
    with pytest.raises(ViewOptionError, match=r"view: the scene 'paper3d' has the states .* the result"):
        gs.viz.view(result, tmp_path / "v.html", gs.scenes.paper3d())
    from grasping_sym.viz.animation import animate  # the drawing functions check it themselves

    with pytest.raises(ViewOptionError, match=r"animate: the scene 'paper3d' has the states"):
        animate(result, tmp_path / "a.gif", gs.scenes.paper3d())
    assert list(tmp_path.iterdir()) == []


def test_a_result_is_one_row_per_time_and_a_column_per_name(result, tmp_path):
    with pytest.raises(InvalidResultError, match=r"x has shape \(501, 3\), but there are 501 times "
                                                 "and 7 state names"):
        gs.SimulationResult(result.t, result.x[:, :3], result.state_names, {}, "radau")
    with pytest.raises(InvalidResultError, match=r"output 'f' has shape \(2,\), but there are 501"):
        gs.SimulationResult(result.t, result.x, result.state_names, {"f": np.zeros(2)}, "radau")
    with pytest.raises(InvalidResultError, match=r"state_names name \['q1'\] more than once"):
        gs.SimulationResult(result.t, result.x, ("q1",) * 7, {}, "radau")
    # save: a directory is not a file name (nothing written)
    for where in (".", tmp_path, tmp_path / ".."):
        with pytest.raises(ResultFileError, match="is a directory; pass a file name"):
            result.save(where)
    (tmp_path / "taken.npz").mkdir()
    with pytest.raises(ResultFileError, match="taken.npz: it is a directory"):
        result.save(tmp_path / "taken")
    with pytest.raises(ResultFileError, match="is a directory: pass the .npz file"):
        gs.SimulationResult.load(tmp_path / "taken.npz")


def test_model_repr_fits_a_screen(paper2d_model):
    text = repr(paper2d_model)
    lines = text.splitlines()
    assert len(lines) <= 12 and all(len(line) <= 110 for line in lines)
    assert lines[0].startswith("Model 'paper2d': 7 states")
    assert "controller  paper" in text and "start       xm = " in text
