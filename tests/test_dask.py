"""``--scheduler``: eval, sweep and score on a Dask cluster give the result files of local runs.

The three cases that take about 15 s each on 2 busy cores are marked slow. A module-wide ``LocalCluster`` of 2 one-thread worker processes (pointed at by address, as an existing
cluster would be) serves most cases; ``score`` also starts its own with ``local:2``. Results are compared
field by field after dropping what differs between any two runs or processes: timing, environment, the
creation time and the per-process note that scores were reused.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

distributed_ = pytest.importorskip("distributed")

from dyadbench import distributed  # noqa: E402
from dyadbench.cli.cluster import ClusterSweep  # noqa: E402
from dyadbench.cli.sweep import Unchanged, reuse_check, written  # noqa: E402
from dyadbench.datasets.base import InMemorySource  # noqa: E402
from dyadbench.datasets.dualtalk import DualTalkSource  # noqa: E402
from dyadbench.errors import ConfigError, DyadbenchError, InputError  # noqa: E402
from dyadbench.protocol.config import ProtocolConfig  # noqa: E402
from tests.hostile_cli import dyadbench, write_root  # noqa: E402
from tests.protocol_clips import isolated_cache, make_source  # noqa: E402,F401

ROOT = Path(__file__).resolve().parents[1]
PER_PROCESS = ("timing", "environment", "created_utc")


@pytest.fixture(scope="module")
def cluster(tmp_path_factory):
    """A 2-worker local cluster whose workers use the tests' cache (they inherit the environment)."""
    old = os.environ.get("DYADBENCH_CACHE")
    os.environ["DYADBENCH_CACHE"] = str(tmp_path_factory.getbasetemp() / "dyadbench-cache")
    try:
        with distributed_.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                       dashboard_address=None) as local:
            yield local
    finally:
        if old is None:
            os.environ.pop("DYADBENCH_CACHE", None)
        else:
            os.environ["DYADBENCH_CACHE"] = old


@pytest.fixture(scope="module")
def root(tmp_path_factory) -> Path:
    return write_root(tmp_path_factory.mktemp("dualtalk"), train=2, test=3)


def comparable(path: Path) -> dict:
    """A result file without the fields that differ between processes (see module docstring)."""
    data = json.loads(path.read_text())
    for key in PER_PROCESS:
        data.pop(key, None)
    data["notes"] = [n for n in data["notes"] if not n.startswith("scores reused")]
    return data


def result_files(folder: Path) -> dict[str, Path]:
    return {str(p.relative_to(folder)): p for p in sorted(folder.rglob("*.json"))}


@pytest.mark.slow  # about 15 s on 2 busy cores
def test_a_sweep_on_the_cluster_writes_the_result_files_of_a_local_sweep(cluster, root, tmp_path, capsys):
    args = ["sweep", "--models", "zero,mean-frame", "--splits", "test", "--contexts", "0,2", "--data", root,
            "--clips", "2"]
    code, output = dyadbench(capsys, *args, "--out", tmp_path / "local")
    assert code == 0, output
    code, output = dyadbench(capsys, *args, "--out", tmp_path / "cluster", "--scheduler", cluster.scheduler_address)
    assert code == 0, output
    local, remote = result_files(tmp_path / "local"), result_files(tmp_path / "cluster")
    assert sorted(remote) == sorted(local) and len(local) == 4  # 2 models x 2 contexts
    for name, path in local.items():
        assert comparable(remote[name]) == comparable(path), name
    # the same sweep again finds every run current
    code, output = dyadbench(capsys, *args, "--out", tmp_path / "cluster", "--scheduler", cluster.scheduler_address)
    assert code == 0 and output.count("skip ") == 4, output


@pytest.mark.slow  # about 15 s on 2 busy cores
def test_eval_and_score_on_the_cluster_equal_their_local_runs(cluster, root, tmp_path, capsys):
    common = ["eval", "--model", "mean-frame", "--context", "1", "--data", root, "--clips", "3"]
    assert dyadbench(capsys, *common, "--out", tmp_path / "local")[0] == 0
    code, output = dyadbench(capsys, *common, "--out", tmp_path / "cluster", "--scheduler", cluster.scheduler_address)
    assert code == 0, output
    local, remote = (comparable(tmp_path / where / "result.json") for where in ("local", "cluster"))
    assert remote.pop("predictions") == str(tmp_path / "cluster" / "predictions")
    assert local.pop("predictions") == str(tmp_path / "local" / "predictions") and remote == local
    preds = tmp_path / "local" / "predictions"
    score = ["score", preds, "--gt", root / "test", "--model", "mean-frame"]
    assert dyadbench(capsys, *score, "--jobs", "1", "--out", tmp_path / "one")[0] == 0
    code, output = dyadbench(capsys, *score, "--scheduler", "local:2", "--out", tmp_path / "many")
    assert code == 0, output
    one, many = comparable(tmp_path / "one" / "result.json"), comparable(tmp_path / "many" / "result.json")
    assert many["metrics"] == one["metrics"] and many["per_clip"] == one["per_clip"] and len(one["per_clip"]["rows"]) == 6
    assert (tmp_path / "many" / "per_clip.csv").read_bytes() == (tmp_path / "one" / "per_clip.csv").read_bytes()


class KillFirstRun(distributed_.WorkerPlugin):
    """Kills the worker process that starts the first task (once: a marker file records it)."""

    def __init__(self, marker: str):
        self.marker = marker

    def transition(self, key, start, finish, **kwargs):
        if finish == "executing" and not os.path.exists(self.marker):
            Path(self.marker).write_text(str(os.getpid()))
            os._exit(1)


def test_a_worker_killed_mid_sweep_leaves_a_complete_correct_sweep(cluster, root, tmp_path, capsys):
    args = ["sweep", "--models", "zero,mean-frame", "--splits", "test", "--contexts", "1", "--data", root,
            "--clips", "2"]
    assert dyadbench(capsys, *args, "--out", tmp_path / "local")[0] == 0
    marker = tmp_path / "killed"
    with distributed_.Client(cluster) as client:
        client.register_plugin(KillFirstRun(str(marker)), name="kill-first-run")
        try:
            code, output = dyadbench(capsys, *args, "--out", tmp_path / "cluster",
                                     "--scheduler", cluster.scheduler_address)
        finally:
            client.unregister_worker_plugin("kill-first-run")
    assert marker.exists()  # a worker did die
    assert code == 0, output
    local, remote = result_files(tmp_path / "local"), result_files(tmp_path / "cluster")
    assert sorted(remote) == sorted(local) and len(local) == 2
    for name, path in local.items():
        assert comparable(remote[name]) == comparable(path), name
    assert not [p for p in (tmp_path / "cluster").rglob("*") if p.is_file() and p.suffix != ".json"]


class UnreadableSource(InMemorySource):
    """A split whose clips cannot be read (the run fails on the worker)."""

    def load(self, clip_id):
        raise InputError(clip_id, "unreadable on purpose")


def test_a_failing_run_is_reported_after_the_others_and_a_rerun_does_only_what_is_missing(cluster, tmp_path,
                                                                                          capsys):
    good, bad = make_source(2), UnreadableSource(list(make_source(2)), dataset="handmade", split="test")
    config = ProtocolConfig(context=1)
    paths = {"good": tmp_path / "good.json", "bad": tmp_path / "bad.json"}
    common = dict(cfg_scale=1.0, weights=None, clips=None, jobs=1, threads=1, extra={}, force=False, per_clip=True)
    with distributed.connected(cluster.scheduler_address):
        runs = ClusterSweep(reuse_check, written, Unchanged)
        runs(paths["bad"], "zero", bad, None, config, **common)
        runs(paths["good"], "zero", good, None, config, **common)
        with pytest.raises(DyadbenchError, match="1 of 2 runs failed"):
            runs.finish()
        err = capsys.readouterr().err
        assert f"error: {paths['bad']}: InputError: c000: unreadable on purpose" in err
        assert paths["good"].is_file() and not paths["bad"].exists()
        before = paths["good"].read_bytes()
        runs(paths["good"], "zero", good, None, config, **common)
        runs(paths["bad"], "zero", good, None, config, **common)  # the data is readable now
        runs.finish()
    out = capsys.readouterr().out
    assert f"skip {paths['good']}" in out and f"-> {paths['bad']}" in out
    assert paths["good"].read_bytes() == before and paths["bad"].is_file()


def _pid(_item) -> int:
    return os.getpid()


@pytest.mark.slow  # about 15 s on 2 busy cores
def test_cuda_tasks_run_only_on_workers_offering_the_gpu_resource(cluster, tmp_path):
    with pytest.raises(ConfigError, match="no worker of the cluster offers the resource GPU=1"):
        with distributed.connected(cluster.scheduler_address, device="cuda"):
            pass
    worker = subprocess.Popen([sys.executable, "-m", "distributed.cli.dask_worker", cluster.scheduler_address,
                               "--nthreads", "1", "--resources", "GPU=1", "--no-nanny", "--no-dashboard"],
                              env={**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)},  # finds this module
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        with distributed_.Client(cluster) as client:
            client.wait_for_workers(3, timeout=60)
        with distributed.connected(cluster.scheduler_address, device="cuda") as active:
            assert active.slots == 1 and active.resources == {"GPU": 1}
            assert set(distributed.cluster_map(_pid, list(range(6)), chunksize=1)) == {worker.pid}
        with distributed.connected(cluster.scheduler_address):  # CPU tasks go anywhere
            assert len(set(distributed.cluster_map(_pid, list(range(40)), chunksize=1))) >= 2
    finally:
        worker.terminate()
        worker.wait(30)


def test_a_worker_that_cannot_see_the_data_says_so(root, tmp_path):
    copy = tmp_path / "test"
    copy.mkdir()
    for f in (root / "test").iterdir():
        (copy / f.name).write_bytes(f.read_bytes())
    shipped = distributed.for_workers(DualTalkSource(copy, "test"))
    assert shipped.digest is None  # recorded data: read at its path, no digest
    for f in copy.iterdir():
        f.unlink()
    copy.rmdir()
    with pytest.raises(InputError, match="cannot see this data folder: a cluster's workers read the data at the "
                                         "same path"):
        shipped.open()


def test_scheduler_is_refused_clearly(capsys, monkeypatch):
    code, output = dyadbench(capsys, "sweep", "--models", "zero", "--scheduler", "local:0")
    assert code == 2 and "expected local:N with N >= 1 workers" in output
    monkeypatch.setitem(sys.modules, "distributed", None)  # Dask not installed
    code, output = dyadbench(capsys, "sweep", "--models", "zero", "--scheduler", "local:2")
    assert code == 2 and "error: --scheduler needs Dask, an optional extra: pip install 'dyadbench[dask]'" in output


def test_without_scheduler_dask_is_never_imported():
    script = ("import sys\nfrom dyadbench.cli import main\nimport dyadbench.cli.sweep, dyadbench.cli.score, "
              "dyadbench.protocol.runner, dyadbench.scoring.parallel\n"
              "print(sorted(m for m in sys.modules if m.split('.')[0] in ('dask', 'distributed')))")
    run = subprocess.run([sys.executable, "-c", script], cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stderr
    assert run.stdout.strip() == "[]"
