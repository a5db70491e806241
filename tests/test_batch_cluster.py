"""The SLURM recipe of docs/batch.md, as far as it runs without SLURM: dask-jobqueue (the
``cluster`` extra) renders the batch script of a worker job from the very
``SLURMCluster(...)`` call the docs give, and that script starts what gonio batch needs:
a single-threaded ``dask worker`` with a nanny (``--job-timeout`` and worker deaths
restart it), pointed at the recipe's scheduler. Submitting the script (``sbatch``) is not
run here; scheduler and worker processes started separately, one SIGKILLed mid-job, are
in tests/test_batch_faults.py."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

pytest.importorskip("dask_jobqueue", reason="gonio[cluster] (dask-jobqueue) is not installed")


def _docs_cluster_call() -> str:
    """The ``SLURMCluster(...)`` call of docs/batch.md's recipe, as the docs write it."""
    text = (ROOT / "docs" / "batch.md").read_text(encoding="utf-8")
    found = re.findall(r"^cluster = (SLURMCluster\(.*?\))\n", text, re.S | re.M)
    assert len(found) == 1, "docs/batch.md has no single SLURMCluster(...) recipe"
    return found[0]


def test_docs_slurm_recipe_renders_a_worker_job_gonio_can_use():
    from dask_jobqueue import SLURMCluster

    with eval(_docs_cluster_call(), {"SLURMCluster": SLURMCluster}) as cluster:  # noqa: S307
        script, address = cluster.job_script(), cluster.scheduler_address
    lines = script.splitlines()
    assert lines[0].startswith("#!")
    directives = [l for l in lines if l.startswith("#SBATCH")]
    assert "#SBATCH -t 02:00:00" in directives and "#SBATCH --mem=4G" in directives
    # one CPU per worker job, asked for once (a second --cpus-per-task would be the docs'
    # own, repeating what dask-jobqueue writes)
    assert [d for d in directives if "cpus-per-task" in d] == ["#SBATCH --cpus-per-task=1"]
    starts = [l.split() for l in lines if "distributed.cli.dask_worker" in l]
    assert len(starts) == 1, script
    words = starts[0]
    assert words[words.index("--nthreads") + 1] == "1"   # gonio's stages bring their threads
    assert "--nanny" in words and "--no-nanny" not in words
    assert address in words and address.startswith("tcp://")
