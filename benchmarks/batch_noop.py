"""A Dask worker preload for the scale benchmark (benchmarks/batch_scale.py): every job a
worker runs does nothing but create its outputs: a 1 × 1 grey PNG for an image (the
contact sheet reads them), else an empty file.

    dask worker --preload benchmarks/batch_noop.py ...

It swaps the runners of :data:`gonio_cli.batch.jobs.RUNNERS` in the worker only; the
driver is the unchanged ``gonio batch``, and everything else a worker does per job (the
attempt log, the receipt, hashing inputs and outputs, the record) runs as usual. So the
jobs cost what gonio batch and Dask add to a job, and nothing of the job itself.
"""

from __future__ import annotations

import base64

from gonio_cli.batch import jobs

#: A 1 × 1 grey PNG (8-bit greyscale, value 128).
PNG = base64.b64decode("iVBORw0KGgoAAAANSUhEUgAAAAEAAAABCAAAAAA6fptVAAAACklEQVR4nGNoAAAAggCBd81y"
                       "tgAAAABJRU5ErkJggg==")


def noop(job, warnings) -> None:  # noqa: ARG001  (a runner's signature)
    """Create the job's outputs (the worker checks that they exist)."""
    for path in job.outputs:
        with open(path, "wb") as fh:
            fh.write(PNG if path.lower().endswith(".png") else b"")
    return None


jobs.RUNNERS.update(dict.fromkeys(jobs.RUNNERS, noop))


def dask_setup(worker) -> None:  # noqa: ARG001  (Dask calls it; the import did the work)
    """Dask's preload hook."""
