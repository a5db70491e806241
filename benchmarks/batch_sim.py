"""A discrete-event simulation of ``gonio batch`` on W workers: a plan's job graph, each
job's cost, the driver and the scheduler as serial servers at measured costs.

The model follows the engine (gonio_cli/batch/engine.py):

* before anything runs, the driver reads and checks the plan and settles what is up to
  date (``plan_s``, serial);
* the driver takes every result that has arrived at once (a batch): it spends
  ``driver_batch_s`` on it (the journal's fsync, the gather) and ``driver_job_s`` per
  job (recording it, submitting what it made ready), then submits the ready jobs;
* the scheduler handles each submitted task in turn (``scheduler_task_s``) before a
  worker can take it;
* a free worker takes the waiting task of highest priority: submission order (Dask's
  default, what the engine does), or the longest path to the end of the graph first;
* a job occupies its worker for its cost plus ``worker_task_s`` (what gonio batch and Dask
  add to a job in the worker) and, for a frame, ``worker_image_s`` (its thumbnail and
  flags for the contact sheet);
* after the last record the driver writes the contact sheet (``sheet_s``, serial).

Efficiency = the jobs' own time / (W × makespan), makespan from the driver's start.
"""

from __future__ import annotations

import heapq
from dataclasses import dataclass
from typing import Mapping, Sequence


@dataclass(frozen=True)
class Costs:
    """Measured costs (s): jobs by role, and the serial parts around them."""

    job_s: Mapping[str, float]          # role (ingest, fit, frame, preview, render) -> s
    worker_task_s: float = 0.0          # worker time a task adds to its job
    worker_image_s: float = 0.0         # and a frame's image for the sheet (thumbnail, flags)
    driver_job_s: float = 0.0           # driver time per job recorded and dispatched
    driver_batch_s: float = 0.0         # driver time per batch of results (fsync, gather)
    scheduler_task_s: float = 0.0       # scheduler time per task
    plan_per_job_s: float = 0.0         # reading, checking and settling the plan, per job
    sheet_per_job_s: float = 0.0        # the contact sheet at the end, per job


@dataclass(frozen=True)
class Result:
    makespan_s: float
    work_s: float
    workers: int
    critical_path_s: float

    @property
    def efficiency(self) -> float:
        return self.work_s / (self.workers * self.makespan_s)


def critical_paths(deps: Mapping[str, Sequence[str]], cost: Mapping[str, float]
                   ) -> dict[str, float]:
    """{key: the longest path of job costs from the start of ``key`` to the graph's end}."""
    users: dict[str, list[str]] = {k: [] for k in deps}
    for k, ds in deps.items():
        for d in ds:
            users[d].append(k)
    order = _topological(deps, users)
    tail: dict[str, float] = {}
    for k in reversed(order):
        tail[k] = cost[k] + max((tail[u] for u in users[k]), default=0.0)
    return tail


def _topological(deps, users) -> list[str]:
    waiting = {k: len(d) for k, d in deps.items()}
    order = [k for k, n in waiting.items() if n == 0]
    for k in order:  # grows while it is walked
        for u in users[k]:
            waiting[u] -= 1
            if waiting[u] == 0:
                order.append(u)
    return order


def simulate(deps: Mapping[str, Sequence[str]], roles: Mapping[str, str], costs: Costs,
             workers: int, order: str = "submission") -> Result:
    """Simulate the plan ``deps`` ({key: keys it needs}, plan order) with ``roles`` ({key:
    role}) on ``workers`` workers; ``order``: "submission" or "critical-path"."""
    cost = {k: costs.job_s[roles[k]] for k in deps}
    extra = {k: costs.worker_task_s + (costs.worker_image_s if roles[k] in ("frame", "render")
                                       else 0.0) for k in deps}
    tail = critical_paths(deps, cost)
    users: dict[str, list[str]] = {k: [] for k in deps}
    for k, ds in deps.items():
        for d in ds:
            users[d].append(k)
    waiting = {k: len(d) for k, d in deps.items()}
    n = len(deps)
    t = costs.plan_per_job_s * n
    events: list[tuple[float, int, str, str]] = []   # (time, seq, kind, key)
    seq = 0
    queue: list[tuple[float, int, str]] = []         # (priority, seq, key): ready tasks
    free, inbox, recorded = workers, [], 0
    driver_free = scheduler_free = t

    def submit(keys: list[str], at: float) -> None:
        nonlocal seq, scheduler_free
        for k in keys:
            scheduler_free = max(scheduler_free, at) + costs.scheduler_task_s
            seq += 1
            prio = -tail[k] if order == "critical-path" else seq
            heapq.heappush(events, (scheduler_free, seq, "queued", k))
            priority[k] = prio

    priority: dict[str, float] = {}
    submit([k for k in deps if waiting[k] == 0], t)
    while events:
        t, _, kind, key = heapq.heappop(events)
        if kind == "queued":
            heapq.heappush(queue, (priority.pop(key), seq, key))
        elif kind == "done":
            free += 1
            inbox.append(key)
        elif kind == "driver":
            driver_free = t
        if inbox and driver_free <= t:  # the driver takes every result that has arrived
            batch, inbox = inbox, []
            recorded += len(batch)
            ready = [u for k in batch for u in users[k] if _count_down(waiting, u)]
            driver_free = t + costs.driver_batch_s + costs.driver_job_s * len(batch)
            seq += 1
            heapq.heappush(events, (driver_free, seq, "driver", ""))
            submit(ready, driver_free)
        while free and queue:
            _, _, k = heapq.heappop(queue)
            free -= 1
            seq += 1
            heapq.heappush(events, (t + cost[k] + extra[k], seq, "done", k))
    if recorded != n:
        raise RuntimeError(f"simulated {recorded} of {n} jobs")
    makespan = max(t, driver_free) + costs.sheet_per_job_s * n
    return Result(makespan, sum(cost.values()), workers, max(tail.values()))


def _count_down(waiting: dict[str, int], key: str) -> bool:
    waiting[key] -= 1
    return waiting[key] == 0
