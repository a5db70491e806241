"""Shared test fixtures. Randomness is seeded per test (STYLE 12)."""

from __future__ import annotations

import os
import tempfile
from dataclasses import dataclass

from gonio_cli.__main__ import use_blas_threads

# One BLAS thread, as a gonio process has: read by OpenBLAS once, when numpy loads, so set
# before the first numpy import.
use_blas_threads()

import numpy as np
import pytest

from gonio_cli import cli, log
from gonio_cli.cache import CACHE_ENV

# Tests never write into the user's cache: one temporary cache for the whole session.
os.environ.setdefault(CACHE_ENV, tempfile.mkdtemp(prefix="gonio-test-cache-"))


@dataclass
class CliResult:
    exit_code: int
    stdout: str
    stderr: str


@pytest.fixture
def run_gonio(capsys):
    """Run ``gonio ARGS…`` in-process; returns :class:`CliResult` (exit code, stdout, stderr)."""

    def _run(*args) -> CliResult:
        capsys.readouterr()  # drop anything printed before
        code = cli.run([str(a) for a in args])
        out, err = capsys.readouterr()
        log.set_quiet(False)
        return CliResult(code, out, err)

    return _run


@pytest.fixture
def rng():
    """A seeded generator; tests needing other seeds make their own."""
    return np.random.default_rng(12345)
