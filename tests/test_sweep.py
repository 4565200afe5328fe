"""gs.sweep on a real dask.distributed LocalCluster: the same numbers as simulate_many, and a
sweep that loses a worker or its own process resumes with no point lost or run twice."""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import threading
import time

import numpy as np
import pytest
import zarr

import grasping_sym as gs
from grasping_sym.cli import main as cli_main
from grasping_sym.errors import SweepStoreBusyError, SweepStoreError
from grasping_sym.sweeps import START, _settling_time, parse_range, store_lock

FD = np.linspace(0.3, 1.0, 100)
Q1 = np.linspace(0.55, 0.75, 100)  # on the scene's start's branch (it turns back at q1 = 0.783)
SETTINGS = dict(method="radau", rtol=1e-3, atol=1e-7, project=True)


@pytest.fixture(scope="module")
def model():
    # the paper's scene with its constraint gains at 0 and projection instead: 0.07 ms a run
    return gs.build(gs.scenes.paper2d(name="sweep2d", gf=0, gl=0, wf=0, wl=0, runtime=("fd",)))


@pytest.fixture(scope="module")
def reference(model):
    """simulate_many over the same 10 000 points, in this process."""
    starts = np.array([model.initial_state(q1=q) for q in Q1])
    x0 = np.repeat(starts[None, :, :], len(FD), axis=0).reshape(-1, starts.shape[1])
    fd = np.repeat(FD, len(Q1))
    return model.simulate_many(3.0, x0=x0, params={"fd": fd}, **SETTINGS)


@pytest.fixture(scope="module")
def client():
    from distributed import Client, LocalCluster

    cluster = LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                           dashboard_address=":0")
    c = Client(cluster)
    yield c
    c.close()
    cluster.close()


def _check(ds, model, reference):
    assert ds.attrs["chunks_done"] == ds.attrs["chunks_total"]
    assert (ds["status"].values == 0).all() and (ds["error"].values == "").all()
    for i, k in enumerate(model.state_names):
        assert np.array_equal(ds[k].values.ravel(), reference.x_final[:, i]), k


def test_a_10000_point_sweep_on_two_worker_processes_matches_simulate_many(model, reference,
                                                                           client, tmp_path):
    ds = gs.sweep(model, {"fd": FD, "q1_0": Q1}, 3.0, store=tmp_path / "s.zarr", client=client,
                  chunk=1000, progress=False, **SETTINGS)
    assert ds["theta"].dims == ("fd", "q1_0") and ds["theta"].shape == (100, 100)
    assert np.array_equal(ds["fd"].values, FD) and np.array_equal(ds["q1_0"].values, Q1)
    _check(ds, model, reference)
    # the workers got the model pickled (runtime.portable), not from this process's memory
    pids = client.run(os.getpid)
    assert os.getpid() not in pids.values() and len(pids) == 2
    again = gs.sweep(model, {"fd": FD, "q1_0": Q1}, 3.0, store=tmp_path / "s.zarr", client=client,
                     chunk=1000, progress=False, **SETTINGS)
    assert again.attrs["chunks_run"] == 0
    _check(again, model, reference)


def test_a_worker_killed_mid_sweep_then_a_rerun_completes_it(model, reference, client, tmp_path):
    store = tmp_path / "k.zarr"
    grid = {"fd": FD, "q1_0": Q1}
    outcome = {}

    def run():
        try:
            outcome["ds"] = gs.sweep(model, grid, 3.0, store=store, client=client, chunk=250,
                                     progress=False, **SETTINGS)
        except Exception as exc:  # noqa: BLE001 - a lost worker may fail the first run
            outcome["error"] = exc

    thread = threading.Thread(target=run)
    thread.start()
    done_at_kill = 0
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline and thread.is_alive():
        try:
            group = zarr.open_group(str(store), mode="r")
            done_at_kill = int(sum(g["done"][:].sum() for _, g in group.groups()))
        except Exception:  # noqa: BLE001 - not created yet
            done_at_kill = 0
        if done_at_kill >= 3:
            break
        time.sleep(0.005)
    pid = next(iter(client.run(os.getpid).values()))
    os.kill(pid, signal.SIGKILL)
    thread.join(120)
    assert not thread.is_alive()
    assert 3 <= done_at_kill < 40, "the worker must die mid-sweep"
    ds = gs.sweep(model, grid, 3.0, store=store, client=client, chunk=250, progress=False,
                  **SETTINGS)
    _check(ds, model, reference)
    if "ds" in outcome:  # Dask ran the lost worker's tasks again: the first run completed
        assert ds.attrs["chunks_run"] == 0 and outcome["ds"].attrs["chunks_run"] == 40
    else:  # the first run failed: the rerun runs only what was not stored
        assert 1 <= ds.attrs["chunks_run"] <= 40 - done_at_kill


def test_a_sweep_whose_process_is_killed_resumes_where_it_stopped(tmp_path):
    model = gs.build(gs.scenes.paper2d(runtime=("fd",)))  # the paper's gains: 1.2 ms a run
    store = tmp_path / "r.zarr"
    script = textwrap.dedent(f"""
        import numpy as np, grasping_sym as gs
        m = gs.build(gs.scenes.paper2d(runtime=("fd",)))
        gs.sweep(m, {{"fd": np.linspace(0.3, 1.0, 400)}}, 3.0, store={str(store)!r}, chunk=10,
                 progress=False, method="radau", rtol=1e-8, atol=1e-10)
    """)
    proc = subprocess.Popen([sys.executable, "-c", script], env=os.environ.copy())
    done = 0
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and proc.poll() is None:
        try:
            group = zarr.open_group(str(store), mode="r")
            done = int(sum(g["done"][:].sum() for _, g in group.groups()))
        except Exception:  # noqa: BLE001 - not created yet
            done = 0
        if done >= 5:
            proc.send_signal(signal.SIGKILL)
            break
        time.sleep(0.005)
    proc.wait(30)
    assert 5 <= done < 40, "the sweep must be killed mid-way"
    fd = np.linspace(0.3, 1.0, 400)
    ds = gs.sweep(model, {"fd": fd}, 3.0, store=store, chunk=10, progress=False, method="radau",
                  rtol=1e-8, atol=1e-10)
    assert ds.attrs["chunks_done"] == 40
    assert ds.attrs["chunks_run"] <= 40 - done  # the chunks stored before the kill stay
    ref = model.simulate_many(3.0, params={"fd": fd}, method="radau", rtol=1e-8, atol=1e-10)
    assert np.array_equal(ds["theta"].values, ref["theta"])


def test_starting_poses_failures_and_measures(model, tmp_path):
    q = np.array([0.4, 0.6, 0.7])  # 0.4: no pose touches the object with the pivot fixed
    ds = gs.sweep(model, gs.sweep.points({"q1_0": q, "fd": [0.5, 0.6, 0.8]}), 2.0,
                  store=tmp_path / "p.zarr", outputs=("f",), measures=("min:f", "settle:theta"),
                  samples=201, progress=False, **SETTINGS)
    assert ds["theta"].dims == ("point",)
    assert ds["status"].values.tolist() == [START, 0, 0]
    assert "UnreachableStartError" in ds["error"].values[0] and np.isnan(ds["theta"].values[0])
    t = np.linspace(0, 2.0, 201)
    for i in (1, 2):
        r = model.simulate(2.0, x0=model.initial_state(q1=q[i]), params={"fd": [0.5, 0.6, 0.8][i]},
                           t_eval=t, **SETTINGS)
        assert ds["f"].values[i] == r["f"][-1] and ds["min_f"].values[i] == r["f"].min()
        assert ds["settle_theta"].values[i] == _settling_time(t, r["theta"][None, :], 1e-3)[0]
        assert np.array_equal(r.x[-1], [ds[k].values[i] for k in model.state_names])


def test_settling_time_is_where_the_quantity_stays_in_its_band():
    t = np.linspace(0, 1, 11)
    y = np.array([[1, 0.5, 0.2, 0.0005, -0.002, 0.0001, 0, 0, 0, 0, 0.0],
                  [0.0] * 11])
    assert _settling_time(t, y, 1e-3).tolist() == [0.5, 0.0]


def test_bad_grids_and_ranges_are_named(model, tmp_path):
    with pytest.raises(ValueError, match="'mass'.*not sweepable"):
        gs.sweep(model, {"mass": [1.0]}, 1.0, store=tmp_path / "x.zarr", progress=False)
    with pytest.raises(ValueError, match="non-finite"):
        gs.sweep(model, {"fd": [0.5, np.nan]}, 1.0, store=tmp_path / "x.zarr", progress=False)
    with pytest.raises(ValueError, match=r"grid\['fd'\] has -1.0: fd must be > 0"):
        gs.sweep(model, {"fd": [0.5, -1.0]}, 1.0, store=tmp_path / "x.zarr", progress=False)
    assert not (tmp_path / "x.zarr").exists()  # refused before anything was written
    with pytest.raises(ValueError, match="not outputs"):
        gs.sweep(model, {"fd": [0.5]}, 1.0, store=tmp_path / "x.zarr", measures=("mean:f",),
                 progress=False)
    with pytest.raises(ValueError, match="method"):
        gs.sweep(model, {"fd": [0.5]}, 1.0, store=tmp_path / "x.zarr", method="cvodes", progress=False)
    assert np.array_equal(parse_range("fd=0.2:1.0:5")[1], np.linspace(0.2, 1.0, 5))
    assert parse_range("q1_0=0.5,0.6")[1].tolist() == [0.5, 0.6]
    for bad in ("fd", "fd=1:2", "fd=1:2:0", "fd=__import__('os')", "fd=nan:1:2", "fd=0.5,inf",
                "fd=0:1:10000000000"):
        with pytest.raises(ValueError, match="--param"):
            parse_range(bad)


def test_the_command_line_sweep_writes_the_store_and_a_heat_map(tmp_path, capsys):
    rc = cli_main(["sweep", "paper2d", "--param", "fd=0.3:1.0:4", "--param", "q1_0=0.5:0.7:5",
                   "--t-final", "1", "--out", str(tmp_path), "--show", "settle_theta", "--quiet"])
    assert rc == 0
    out = capsys.readouterr().out
    assert "points           20 (16 ok, 4 with status -12)" in out
    assert (tmp_path / "settle_theta.png").stat().st_size > 10_000
    ds = gs.sweep.open(tmp_path / "sweep.zarr")
    assert ds["settle_theta"].shape == (4, 5)
    rc = cli_main(["sweep", "paper2d", "--param", "fd=0.3:1.0:4", "--param", "q1_0=0.5:0.7:5",
                   "--t-final", "1", "--out", str(tmp_path), "--show", "failure", "--quiet"])
    assert rc == 0 and "run now          0 of 1 chunks" in capsys.readouterr().out
    assert (tmp_path / "failure.png").is_file()


# ------------------------------------------------------------------ the store damaged or shared
SMALL = dict(chunk=2, progress=False, **SETTINGS)
SMALL_FD = np.linspace(0.3, 1.0, 6)


def test_deleted_and_corrupted_chunks_are_named_then_run_again_bit_for_bit(model, tmp_path):
    store = tmp_path / "d.zarr"
    first = gs.sweep(model, {"fd": SMALL_FD}, 0.5, store=store, **SMALL)
    assert first.attrs["chunks_done"] == 3 and (first["status"].values == 0).all()
    group = store / first.attrs["group"]
    for v in (*model.state_names, "status", "error"):  # every file of chunk 1 deleted
        (group / v / "c" / "1").unlink()
    (group / "theta" / "c" / "0").write_bytes(b"not zstd at all")  # chunk 0 of theta damaged
    with pytest.raises(SweepStoreError, match=r"2 chunks marked done .* chunk 0 \(points 0 to 1\): "
                                              r"theta unreadable: .*Zstd.*Run the same gs.sweep"):
        gs.sweep.open(store)
    with pytest.warns(UserWarning, match=r"2 chunks marked done are missing or unreadable and are run "
                                         r"again: chunk 0 \(theta unreadable.*chunk 1 \(theta missing, q1 missing"):
        again = gs.sweep(model, {"fd": SMALL_FD}, 0.5, store=store, **SMALL)
    assert again.attrs["chunks_run"] == 2 and again.attrs["chunks_damaged"] == [0, 1]
    for v in first.data_vars:
        assert np.array_equal(again[v].values, first[v].values), v
    assert gs.sweep.open(store).attrs["chunks_done"] == 3


def test_a_store_that_is_a_file_or_a_foreign_directory_is_named(model, tmp_path):
    path = tmp_path / "s.zarr"
    path.write_text("my notes")
    with pytest.raises(SweepStoreError, match="s.zarr is a file, not a Zarr store"):
        gs.sweep(model, {"fd": SMALL_FD}, 0.5, store=path, **SMALL)
    with pytest.raises(SweepStoreError, match="is a file, not a Zarr store"):
        gs.sweep.open(path)
    with pytest.raises(SweepStoreError, match="s.zarr is a file, not a directory"):
        gs.sweep(model, {"fd": SMALL_FD}, 0.5, store=path / "inner.zarr", **SMALL)
    assert path.read_text() == "my notes"
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "thesis.tex").write_text("x")
    with pytest.raises(SweepStoreError, match="not a Zarr store .*no zarr.json"):
        gs.sweep(model, {"fd": SMALL_FD}, 0.5, store=mine, **SMALL)
    assert os.listdir(mine) == ["thesis.tex"]
    with pytest.raises(SweepStoreError, match="no sweep store at"):
        gs.sweep.open(tmp_path / "nothing.zarr")


_HOLDER = """
import sys
from grasping_sym.sweeps import store_lock
with store_lock(sys.argv[1]):
    print("held", flush=True)
    sys.stdin.read()
"""


def test_a_second_writer_is_refused_by_name_and_a_killed_ones_lock_does_not_block(model, tmp_path):
    store = tmp_path / "w.zarr"
    holder = subprocess.Popen([sys.executable, "-c", _HOLDER, str(store)], stdin=subprocess.PIPE,
                              stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "held"
        with pytest.raises(SweepStoreBusyError, match=rf"another sweep \(pid {holder.pid} on .*\) is "
                                                      r"writing the store .*w.zarr; wait for it"):
            gs.sweep(model, {"fd": SMALL_FD}, 0.5, store=store, **SMALL)
        assert not store.exists()  # refused before anything was written
    finally:
        holder.kill()  # SIGKILL: its lock file stays, its lock goes with it
        holder.wait(30)
    assert (tmp_path / "w.zarr.lock").is_file()
    ds = gs.sweep(model, {"fd": SMALL_FD}, 0.5, store=store, **SMALL)
    assert ds.attrs["chunks_done"] == 3 and not (tmp_path / "w.zarr.lock").exists()
    with store_lock(store):  # in this process too: a second writer (another thread) is refused
        with pytest.raises(SweepStoreBusyError, match=rf"pid {os.getpid()}"):
            gs.sweep(model, {"fd": SMALL_FD}, 0.5, store=store, **SMALL)
