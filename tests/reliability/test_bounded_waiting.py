"""Bounded waiting: joining a Ray cluster (--address) has a time limit and ends in one line before
anything is written, for an unreachable port, a listener that never answers as Ray, a malformed or empty
address; a real local cluster is joined. Loopback addresses only."""

from __future__ import annotations

import socket
import time

import pytest

from irlsim import executor
from irlsim.cli import main
from tests.conftest import TINY_COLLECT

ray = pytest.importorskip("ray")


@pytest.fixture()
def silent_port():
    """A loopback port that accepts connections and never says a word (ray.init alone waits for ever)."""
    with socket.socket() as srv:
        srv.bind(("127.0.0.1", 0))
        srv.listen(8)
        yield srv.getsockname()[1]


def _commands(out, address: str) -> list[list[str]]:
    ray_args = ["--executor", "ray", "--address", address, "--episode-timeout", "5", "--out", str(out)]
    collect = ["collect", "--config", "configs/collect/tiny.toml", *TINY_COLLECT, *ray_args]
    drive = ["drive", "--model", "expert", "--max-cycles", "3", "--frames", "0", *ray_args]
    return [collect, drive]


@pytest.mark.parametrize(
    "address, needle",
    [
        ("127.0.0.1:1", "cannot reach the Ray cluster at 127.0.0.1:1 (Connection refused)"),
        ("silent", "did not answer as a Ray cluster within 3 s"),
        ("", "is not host:port"),
        ("127.0.0.1", "is not host:port"),
        ("127.0.0.1:70000", "is not host:port"),
    ],
)
def test_an_unusable_address_is_one_line_in_bounded_time_before_anything_is_written(
    silent_port, tmp_path, capsys, monkeypatch, address, needle
):
    monkeypatch.setattr(executor, "RAY_JOIN_TIMEOUT_S", 3.0)
    monkeypatch.delenv("RAY_ADDRESS", raising=False)
    if address == "silent":
        address = f"127.0.0.1:{silent_port}"
    for cmd in _commands(tmp_path / "out", address):
        t0 = time.monotonic()
        capsys.readouterr()
        assert main(cmd) == 2, cmd[0]
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and needle in err[0], err
        assert time.monotonic() - t0 < 30
        assert not (tmp_path / "out").exists()  # no dataset folder, no incomplete manifest
    assert not ray.is_initialized()


def test_a_real_local_cluster_is_joined_within_the_limit(monkeypatch):
    from ray.cluster_utils import Cluster

    monkeypatch.delenv("RAY_ADDRESS", raising=False)
    assert not ray.is_initialized()
    cluster = Cluster(initialize_head=True, head_node_args={"num_cpus": 1, "include_dashboard": False})
    try:
        executor.check_executor("ray", 1, cluster.address)
        assert ray.is_initialized()
        result = executor.run_jobs(abs, [executor.Job("a", -3)], executor="ray", address=cluster.address)
        assert result.results == {"a": 3}
        assert not ray.is_initialized()  # joined by the check, left by the run
    finally:
        ray.shutdown()
        cluster.shutdown()
