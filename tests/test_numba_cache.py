"""The error-diffusion kernel is compiled once per machine, not once per process.

Each check runs a fresh Python process (the in-process dispatcher would hide a cache miss)
with its own empty ``NUMBA_CACHE_DIR`` and reads numba's own counters of the kernel's
dispatcher (``stats.cache_hits`` / ``stats.cache_misses``): the first process misses and
writes the cache, the second loads it and compiles nothing. No timing is involved.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np

from gonio_cli.halftone import diffusion

ROOT = Path(__file__).resolve().parent.parent

#: Runs the kernel on a small image through the public path and prints what numba did.
PROBE = """
import json, sys
import numpy as np
from gonio_cli.halftone import diffusion, halftone
diffusion.compile_kernel("numba")  # the C build, where present, needs no cache
coverage = np.full((16, 16, 3), 0.2, dtype=np.float32)
labels = halftone(coverage, "floyd-steinberg").labels
fn = diffusion._KERNEL["numba"]
print(json.dumps({"hits": sum(fn.stats.cache_hits.values()),
                  "misses": sum(fn.stats.cache_misses.values()),
                  "status": diffusion.kernel_status(),
                  "labels": labels.tolist()}))
"""


def probe(env_extra: dict[str, str]) -> dict:
    env = {k: v for k, v in os.environ.items()
           if not k.startswith("NUMBA_CACHE")}
    env.update(env_extra)
    done = subprocess.run([sys.executable, "-c", PROBE], cwd=ROOT, env=env,
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout.strip().splitlines()[-1])


def test_second_process_loads_the_kernel_from_the_cache(tmp_path):
    env = {"NUMBA_CACHE_DIR": str(tmp_path / "numba")}
    first = probe(env)
    assert first["misses"] >= 1 and first["hits"] == 0 and first["status"] == "compiled"
    # the cache went where NUMBA_CACHE_DIR says, not beside the package
    assert any(p.suffix == ".nbc" for p in (tmp_path / "numba").rglob("*"))
    second = probe(env)
    assert second["hits"] >= 1 and second["misses"] == 0 and second["status"] == "cache"
    assert second["labels"] == first["labels"]


def test_no_writable_cache_folder_still_halftones():
    """When numba finds no folder it may write (here: only the zip-archive locator is
    allowed, which does not apply to a plain file), the kernel is compiled uncached."""
    result = probe({"NUMBA_CACHE_LOCATOR_CLASSES": "ZipCacheLocator"})
    assert result["status"] == "compiled-uncached"
    expected = diffusion.diffuse_reference(np.full((16, 16, 3), 0.2, np.float32),
                                           diffusion.FLOYD_STEINBERG)
    assert result["labels"] == expected.tolist()


def test_screens_do_not_import_numba():
    """Only error diffusion needs numba; importing the package and running an ordered
    screen must not pay for its import."""
    code = ("import sys, numpy as np\n"
            "from gonio_cli.halftone import halftone\n"
            "import gonio_cli.cli\n"
            "halftone(np.full((8, 8, 3), 0.2, np.float32), 'bayer')\n"
            "print('numba' in sys.modules)")
    done = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True,
                          text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "False"


def test_status_before_loading():
    code = ("from gonio_cli.halftone import diffusion\n"
            "print(diffusion.kernel_status())")
    done = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True,
                          text=True, timeout=120)
    assert done.stdout.strip() == "not-loaded", done.stderr
