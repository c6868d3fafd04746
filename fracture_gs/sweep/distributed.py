"""The ranks of a sweep: launch environment, one device per rank, the process group, and the
coordination of rank 0 with the others through the process group's key-value store.

Launch. Under `torchrun` every process finds RANK, WORLD_SIZE, LOCAL_RANK, LOCAL_WORLD_SIZE,
MASTER_ADDR and MASTER_PORT in its environment (`launch_from_env`); without them the sweep is one
process and no process group is made. A half-set environment (WORLD_SIZE without RANK, a RANK
outside 0..WORLD_SIZE-1, no MASTER_ADDR) is a `LaunchError` with one sentence saying what is wrong.

Devices. `--device cuda` gives rank r the GPU cuda:LOCAL_RANK (one GPU per rank); more ranks on a
node than it has GPUs is a LaunchError, as is a cuda:K that does not exist. `auto` is CUDA when
there is a GPU, else the CPU; it assumes every node sees the same kind of device (pass --device
explicitly on a mixed cluster, or the ranks would pick different backends).

Process group. Backend `nccl` when the ranks run on CUDA (one GPU each), `gloo` on the CPU, with
`timeout` = the rank timeout, so a rank that never joins is reported instead of waited on forever.
`NCCL_NVLS_ENABLE` is set to "0" (when unset) before the group is made: NVLink SHARP multicast
objects cannot always be created on shared or partitioned machines (lent nodes, MIG, containers
without the fabric manager's multicast rights), and NCCL then fails or hangs at its first
collective instead of falling back; a sweep moves a few kilobytes and gains nothing from it. The
sweep itself runs no NCCL collective (NCCL connects lazily, so no communicator is ever created);
the group exists for its store and for future tensor work (docs/scaling.md).

Coordination (`StoreCoordinator`), through the group's TCP store, never through a blocking
collective, so that a fast rank may wait for a slow one as long as the slow one is alive:

1. every rank publishes the ids of the cells it has cached; rank 0 merges them, deals the
   remaining cells out (by estimated cost, `driver.deal`) and publishes the plan;
2. every rank runs its cells (and writes each to the cache as it finishes);
3. every rank > 0 publishes its rows and a done mark; rank 0 waits for all of them and writes the
   tables.

Liveness: a thread on each rank bumps a heartbeat counter every `beat_s`; rank 0 watches every
other rank's counter and the others watch rank 0's. A counter that stops for `timeout_s` (or a
store that stops answering: rank 0 hosts it unless torchrun's agent does) marks that rank dead;
the survivors finish and cache their own cells, rank 0 still writes the tables with the dead
rank's unfinished cells marked `missing`, and the run ends with `RankFailure`, one sentence
naming the rank. (Under torchrun on one node the agent also stops every rank when one process
dies; its finished cells are cached either way, and the same command resumes.)
"""

from __future__ import annotations

import datetime
import json
import os
import re
import threading
import time
from dataclasses import dataclass
from typing import Callable, Optional

from ..errors import FractureGSError

PREFIX = "fracture_gs/sweep"
"""Key prefix of the sweep's entries in the process group's store."""


class LaunchError(FractureGSError, ValueError):
    """A launch that cannot work: inconsistent torchrun variables, a device that does not exist,
    more ranks than GPUs, ranks that never met. One sentence with the fix."""


class RankFailure(FractureGSError, RuntimeError):
    """A rank died or stopped answering during a sweep; `rank` names it."""

    def __init__(self, message: str, rank: int):
        super().__init__(message)
        self.rank = rank


@dataclass(frozen=True)
class Launch:
    """Where this process sits in the launch (the torchrun variables, checked)."""

    rank: int = 0
    """Global rank, 0..world_size-1 (RANK)."""
    world_size: int = 1
    """Number of processes (WORLD_SIZE); 1 = no process group."""
    local_rank: int = 0
    """Rank on this node (LOCAL_RANK): the GPU index with --device cuda."""
    local_world_size: int = 1
    """Processes on this node (LOCAL_WORLD_SIZE; default WORLD_SIZE)."""
    master: str = ""
    """MASTER_ADDR:MASTER_PORT, the rendezvous of the process group ("" for one process)."""

    @property
    def distributed(self) -> bool:
        return self.world_size > 1

    @property
    def tag(self) -> str:
        """`[rank r/W]`, the prefix of every line a rank prints."""
        return f"[rank {self.rank}/{self.world_size}]"


def _env_int(env, name: str) -> Optional[int]:
    text = env.get(name)
    if text is None or text == "":
        return None
    try:
        return int(text)
    except ValueError:
        raise LaunchError(
            f"{name}={text!r} is not an integer; torchrun sets it, so start the ranks with torchrun or fix {name}."
        ) from None


def launch_from_env(env=None) -> Launch:
    """The launch described by the environment (torchrun's variables), or a 1-process launch."""
    env = os.environ if env is None else env
    rank, world = _env_int(env, "RANK"), _env_int(env, "WORLD_SIZE")
    local_rank, local_world = _env_int(env, "LOCAL_RANK"), _env_int(env, "LOCAL_WORLD_SIZE")
    fix = (
        "start the ranks with torchrun (it sets RANK, LOCAL_RANK, WORLD_SIZE, MASTER_ADDR and MASTER_PORT) "
        "or unset them all for a 1-process run"
    )
    if rank is None and world is None:
        if local_rank is not None:
            raise LaunchError(f"LOCAL_RANK={local_rank} is set but RANK and WORLD_SIZE are not; {fix}.")
        return Launch()
    if rank is None:
        raise LaunchError(f"WORLD_SIZE={world} is set but RANK is not; {fix}.")
    if world is None:
        raise LaunchError(f"RANK={rank} is set but WORLD_SIZE is not; {fix}.")
    if world < 1:
        raise LaunchError(f"WORLD_SIZE={world} must be at least 1; {fix}.")
    if not 0 <= rank < world:
        raise LaunchError(f"RANK={rank} is outside 0..{world - 1} (WORLD_SIZE={world}); {fix}.")
    local_rank = rank if local_rank is None else local_rank
    local_world = world if local_world is None else local_world
    if not 0 <= local_rank < local_world <= world:
        raise LaunchError(
            f"LOCAL_RANK={local_rank} and LOCAL_WORLD_SIZE={local_world} do not fit WORLD_SIZE={world} "
            f"(need 0 <= LOCAL_RANK < LOCAL_WORLD_SIZE <= WORLD_SIZE); {fix}."
        )
    master = ""
    if world > 1:
        for name in ("MASTER_ADDR", "MASTER_PORT"):
            if not env.get(name):
                raise LaunchError(
                    f"WORLD_SIZE={world} but {name} is not set; torchrun sets it, or export MASTER_ADDR=<rank 0's "
                    "host> and MASTER_PORT=<a free port> on every rank."
                )
        master = f"{env['MASTER_ADDR']}:{env['MASTER_PORT']}"
    return Launch(rank, world, local_rank, local_world, master)


def _cuda() -> tuple[int, str]:
    """(CUDA device count, why none when 0)."""
    import torch

    if not torch.cuda.is_available():
        build = "a CPU-only torch build" if torch.version.cuda is None else "no CUDA device or driver"
        return 0, f"torch.cuda.is_available() is False: {build}"
    visible = os.environ.get("CUDA_VISIBLE_DEVICES")
    return torch.cuda.device_count(), (f"CUDA_VISIBLE_DEVICES={visible}" if visible is not None else "")


def resolve_device(flag: Optional[str], launch: Launch) -> str:
    """`auto|cpu|cuda|cuda:N` → this rank's device; raises LaunchError with the fix."""
    spec = "auto" if flag is None else str(flag).strip().lower()
    if not re.fullmatch(r"auto|cpu|cuda(:\d+)?", spec):
        raise LaunchError(
            f"--device {flag!r} is not a device; use auto, cpu, cuda (rank r gets cuda:LOCAL_RANK) or cuda:N."
        )
    if spec == "cpu":
        return "cpu"
    count, why = _cuda()
    if spec == "auto":
        if count == 0:
            return "cpu"
        spec = "cuda"
    if spec.startswith("cuda:"):
        index = int(spec.split(":")[1])
        if index >= count and count == 0:
            raise LaunchError(f"--device {spec} does not exist; this machine has no CUDA device ({why}); use cpu.")
        if index >= count:
            raise LaunchError(
                f"--device {spec} does not exist; this machine has {count} CUDA device(s), cuda:0 to cuda:{count - 1}; "
                "pick one of those, or cpu."
            )
        if launch.distributed:
            raise LaunchError(
                f"--device {spec} would put all {launch.world_size} ranks on one GPU; use --device cuda, which "
                "gives each rank its own GPU, cuda:LOCAL_RANK."
            )
        return spec
    if count == 0:
        raise LaunchError(f"--device cuda was requested but this machine has no CUDA device ({why}); use --device cpu.")
    if launch.local_world_size > count:
        extra = f" ({why})" if why else ""
        raise LaunchError(
            f"{launch.local_world_size} ranks were started on this node but it has {count} GPU(s){extra}; "
            f"start one rank per GPU (torchrun --nproc-per-node {count}) or use --device cpu."
        )
    return f"cuda:{launch.local_rank}"


def backend_for(device: str) -> str:
    """nccl for a rank with its own GPU (when this torch has NCCL), gloo otherwise."""
    import torch.distributed as dist

    return "nccl" if device.startswith("cuda") and dist.is_nccl_available() else "gloo"


# --------------------------------------------------------------------------------------------
# coordination


class Coordinator:
    """One process: the plan is made here and the rows are already all here."""

    def __init__(self, launch: Launch, device: str):
        self.launch, self.device = launch, device
        self.dead: dict[int, str] = {}

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def close(self) -> None:
        """Release the process group (nothing for one process)."""

    def plan(self, cached: dict, make_plan: Callable[[list], dict]) -> dict:
        """Publish this rank's cached cell statuses; return the plan rank 0 makes from everyone's."""
        return make_plan([cached])

    def finish(self, rows: dict) -> Optional[list[dict]]:
        """Hand this rank's rows to rank 0; on rank 0, return every live rank's rows (by rank)."""
        return [rows]

    def failure(self) -> Optional[RankFailure]:
        """After `finish` on rank 0: the first dead rank as a RankFailure, or None."""
        return None


class StoreCoordinator(Coordinator):
    """Several processes: the process group, its store, the heartbeat thread (module docstring)."""

    def __init__(self, launch: Launch, device: str, timeout_s: float = 300.0, beat_s: float = 2.0):
        super().__init__(launch, device)
        self.timeout_s, self.beat_s = float(timeout_s), float(beat_s)
        self.store = None
        self._stop = threading.Event()
        self._thread: Optional[threading.Thread] = None
        self._failed = False

    # ---- set-up and teardown ---------------------------------------------------------------
    def __enter__(self):
        import torch
        import torch.distributed as dist
        from torch.distributed import distributed_c10d

        os.environ.setdefault("NCCL_NVLS_ENABLE", "0")  # see the module docstring
        backend = backend_for(self.device)
        if self.device.startswith("cuda"):
            torch.cuda.set_device(torch.device(self.device))
        L = self.launch
        try:
            dist.init_process_group(
                backend,
                rank=L.rank,
                world_size=L.world_size,
                timeout=datetime.timedelta(seconds=self.timeout_s),
            )
        except Exception as exc:  # noqa: BLE001 - every failure to meet is the same sentence
            raise LaunchError(
                f"rank {L.rank} could not meet the other {L.world_size - 1} rank(s) at {L.master} within "
                f"{self.timeout_s:g} s ({_first_line(exc)}); start every rank with the same torchrun command and "
                "check MASTER_ADDR, MASTER_PORT and the firewall."
            ) from None
        self.backend = backend
        self.store = distributed_c10d._get_default_store()  # the group's TCP store (no public accessor)
        self._thread = threading.Thread(target=self._heartbeat, name="fgs-sweep-heartbeat", daemon=True)
        self._thread.start()
        return self

    def close(self) -> None:
        import torch.distributed as dist

        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=self.beat_s + 5)
        if dist.is_initialized() and not self._failed and not self.dead:
            dist.destroy_process_group()

    # ---- liveness --------------------------------------------------------------------------
    def _key(self, *parts) -> str:
        return "/".join((PREFIX, *map(str, parts)))

    def _heartbeat(self) -> None:
        """Bump this rank's counter; watch the others' (rank 0) or rank 0's (the rest)."""
        r, W = self.launch.rank, self.launch.world_size
        watch = [q for q in range(W) if q != r] if r == 0 else [0]
        seen = {q: (-1, time.monotonic()) for q in watch}
        while True:
            try:
                self.store.add(self._key("beat", r), 1)
                now = time.monotonic()
                for q in watch:
                    if q in self.dead or self.store.check([self._key("done", q)]):
                        continue
                    value = self.store.add(self._key("beat", q), 0)
                    if value != seen[q][0]:
                        seen[q] = (value, now)
                    elif now - seen[q][1] > self.timeout_s:
                        self.dead[q] = f"sent no heartbeat for {self.timeout_s:g} s (it died or hangs)"
            except Exception as exc:  # noqa: BLE001 - a store that stops answering is a dead host
                if r != 0:
                    self.dead.setdefault(
                        0, f"stopped answering: the store at {self.launch.master} is gone ({_first_line(exc)})"
                    )
                else:
                    self._failed = True
                return
            if self._stop.wait(self.beat_s):
                return

    def _failure(self, rank: int, while_doing: str) -> RankFailure:
        self._failed = True
        L = self.launch
        return RankFailure(
            f"rank {rank} of {L.world_size} {self.dead.get(rank, 'stopped')} (seen from rank {L.rank}) while "
            f"{while_doing}; the cells every live rank finished are cached, so rerunning the same command resumes "
            "from them.",
            rank,
        )

    def _wait(self, keys: list[str], owners: list[int], while_doing: str) -> None:
        """Block until every key exists; a dead owner (or an abort from rank 0) raises RankFailure."""
        while True:
            missing = [(k, q) for k, q in zip(keys, owners) if not self.store.check([k])]
            if not missing:
                return
            for _, q in missing:
                if q in self.dead:
                    raise self._failure(q, while_doing)
            if self.launch.rank != 0 and 0 in self.dead:
                raise self._failure(0, while_doing)
            if self.launch.rank != 0 and self.store.check([self._key("abort")]):
                self._failed = True
                raise RankFailure(self.store.get(self._key("abort")).decode(), 0)
            time.sleep(0.1)

    # ---- the protocol ----------------------------------------------------------------------
    def plan(self, cached: dict, make_plan: Callable[[list], dict]) -> dict:
        r, W = self.launch.rank, self.launch.world_size
        self.store.set(self._key("cached", r), json.dumps(cached))
        if r == 0:
            keys = [self._key("cached", q) for q in range(W)]
            try:
                self._wait(keys, list(range(W)), "the ranks were listing their cached cells")
            except RankFailure as exc:
                self.store.set(self._key("abort"), str(exc))
                raise
            plan = make_plan([json.loads(self.store.get(k)) for k in keys])
            self.store.set(self._key("plan"), json.dumps(plan))
            return plan
        self._wait([self._key("plan")], [0], "waiting for rank 0's plan")
        return json.loads(self.store.get(self._key("plan")))

    def finish(self, rows: dict) -> Optional[list[dict]]:
        r, W = self.launch.rank, self.launch.world_size
        if r != 0:
            if 0 in self.dead:
                raise self._failure(0, "this rank ran its cells")
            self.store.set(self._key("rows", r), json.dumps(rows))
            self.store.set(self._key("done", r), "1")
            return None
        gathered = [rows]
        for q in range(1, W):
            while q not in self.dead and not self.store.check([self._key("done", q)]):
                time.sleep(0.1)
            if q not in self.dead:
                gathered.append(json.loads(self.store.get(self._key("rows", q))))
        return gathered

    def failure(self) -> Optional[RankFailure]:
        """After `finish` on rank 0: the first dead rank as a RankFailure, or None."""
        if not self.dead:
            return None
        q = min(self.dead)
        return self._failure(q, "the sweep ran (its unfinished cells are marked missing in the tables)")


def _first_line(exc: BaseException) -> str:
    text = " ".join(str(exc).split()) or type(exc).__name__
    return text if len(text) <= 200 else text[:197] + "..."


def coordinator(launch: Launch, device: str, timeout_s: float = 300.0, beat_s: float = 2.0) -> Coordinator:
    """The coordinator for this launch: plain for one process, store-based for several."""
    if launch.distributed:
        return StoreCoordinator(launch, device, timeout_s, beat_s)
    return Coordinator(launch, device)
