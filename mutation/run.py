"""Mutation testing of fracture-gs with cosmic-ray: does the suite fail when the code is wrong?

    python mutation/run.py map  --jobs 16                       # which test runs which line (once per suite change)
    python mutation/run.py run  --workers 16 fracture_gs/sweep  # mutate, test, score
    python mutation/run.py run  --workers 2 --sample 40 fracture_gs/sim/boundary.py
    python mutation/run.py report                               # score per module, survivors with their diffs

Why cosmic-ray: it mutates the real source file on disk (AST operators), so the Warp kernels, which
Warp compiles from their source text, are mutated like any other code (mutmut 3 rewrites every
function into a trampoline that Warp cannot compile); its sessions are SQLite files that resume
after an interruption; and its HTTP workers spread one session over many cores (16 on the lent
machine). The operator set (`OPERATORS` below) is the realistic-bug subset: swapped arithmetic,
off-by-one comparisons and constants, dropped negations, flipped booleans, skipped loops. Each
mutant runs only the tests that execute its line (`pick_tests.py`).
"""

from __future__ import annotations

import argparse
import json
import os
import random
import re
import shutil
import signal
import subprocess
import sys
import time
from collections import defaultdict
from pathlib import Path

import tomllib

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
STATE = HERE / ".state"
DEFAULT_TARGETS = ["fracture_gs/sim", "fracture_gs/io/config", "fracture_gs/capture", "fracture_gs/sweep"]

# The realistic-bug operators (regular expressions over cosmic-ray's operator names).
OPERATORS = [
    r"core/ReplaceBinaryOperator_(Add_Sub|Sub_Add|Mul_Div|Div_Mul|Pow_Mul|FloorDiv_Mul|Mod_FloorDiv)$",
    r"core/ReplaceComparisonOperator_(Lt_LtE|LtE_Lt|Gt_GtE|GtE_Gt|Eq_NotEq|NotEq_Eq|Lt_Gt|Gt_Lt|Is_IsNot|IsNot_Is)$",
    r"core/ReplaceUnaryOperator_(USub_UAdd|Delete_USub|Delete_Not)$",
    r"core/(AddNot|ReplaceTrueWithFalse|ReplaceFalseWithTrue|ReplaceAndWithOr|ReplaceOrWithAnd)$",
    r"core/(ReplaceBreakWithContinue|ReplaceContinueWithBreak|NumberReplacer|ZeroIterationForLoop)$",
]
PRAGMA = "pragma: no mutate"


def target_files(patterns: list[str]) -> list[str]:
    """Package-relative .py files under each pattern (a folder, a file or a glob)."""
    out: list[str] = []
    for pat in patterns or DEFAULT_TARGETS:
        p = ROOT / pat
        if p.is_dir():
            out += [str(f.relative_to(ROOT)) for f in sorted(p.rglob("*.py"))]
        elif p.is_file():
            out.append(pat)
        else:
            out += [str(f.relative_to(ROOT)) for f in sorted(ROOT.glob(pat))]
    return [f for f in dict.fromkeys(out) if not f.endswith("__init__.py")]


# ---------------------------------------------------------------- map: which test runs which line
def _shard_cmd(i: int, files: list[str], pytest_args: list[str]) -> list[str]:
    cmd = [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "--cov=fracture_gs"]
    cmd += ["--cov-context=test", "--cov-report=", f"--junitxml={STATE / f'junit.{i}.xml'}", "--durations=0"]
    return [*cmd, *pytest_args, *files]


def _run_shards(shards: list[list[str]], first: int, jobs: int, pytest_args: list[str]) -> dict[int, tuple[int, list]]:
    """Run each shard of test files under coverage (its data in .coverage.<index>, index from `first`), at most
    `jobs` at once; returns {index: (exit code, files)}."""
    done: dict[int, tuple[int, list]] = {}
    running: list = []
    queue = [(first + k, shard) for k, shard in enumerate(shards) if shard]
    while queue or running:
        while queue and len(running) < jobs:
            i, shard = queue.pop(0)
            env = dict(os.environ, COVERAGE_FILE=str(STATE / f".coverage.{i}"))
            log = open(STATE / f"map.{i}.log", "w")
            running.append(
                (
                    i,
                    shard,
                    subprocess.Popen(
                        _shard_cmd(i, shard, pytest_args), cwd=ROOT, env=env, stdout=log, stderr=subprocess.STDOUT
                    ),
                )
            )
        time.sleep(0.2)
        for item in list(running):
            i, shard, proc = item
            if proc.poll() is not None:
                done[i] = (proc.returncode, shard)
                running.remove(item)
    return done


COMPLETED = (0, 1, 5)  # pytest ran to its end: all passed, some failed, none collected


def cmd_map(args) -> int:
    """Run the suite under coverage with one context per test; keep {module: {line: [test ids]}}. A shard whose
    pytest died (a fatal error or signal leaves no coverage data) is run again one file per process, so only the
    file that dies is missing from the map; those are listed, kept in map_gaps.json, and `run` warns of them
    (their tests' kills would otherwise count as survivors)."""
    STATE.mkdir(exist_ok=True)
    for old in STATE.glob(".coverage.*"):
        old.unlink()
    files = sorted({str(p.relative_to(ROOT)) for g in args.tests.split(",") for p in (ROOT / "tests").glob(g)})
    t0 = time.time()
    shards = [files[i :: args.jobs] for i in range(args.jobs)]
    done = _run_shards(shards, 0, args.jobs, args.pytest_args)
    crashed = [i for i, (code, _) in done.items() if code not in COMPLETED]
    gaps: list[str] = []
    if crashed:
        alone = [[f] for i in crashed for f in done[i][1]]
        print(f"{len(crashed)} shard(s) died ({', '.join(f'map.{i}.log' for i in crashed)}); their {len(alone)} "
              "files run again one a process", flush=True)  # fmt: skip
        for i in crashed:  # their partial data is not trusted
            done.pop(i)
            (STATE / f".coverage.{i}").unlink(missing_ok=True)
            (STATE / f"junit.{i}.xml").unlink(missing_ok=True)
        again = _run_shards(alone, max(done, default=-1) + 1 + len(crashed), args.jobs, args.pytest_args)
        for i, (code, shard) in again.items():
            if code not in COMPLETED:
                gaps += shard
                (STATE / f".coverage.{i}").unlink(missing_ok=True)
                (STATE / f"junit.{i}.xml").unlink(missing_ok=True)
        done.update({i: r for i, r in again.items() if r[0] in COMPLETED})
    (STATE / "map_gaps.json").write_text(json.dumps(sorted(gaps)))
    failed = [i for i, (code, _) in done.items() if code != 0]
    print(f"coverage shards done in {time.time() - t0:.0f} s; shards with failing tests: {len(failed)}", flush=True)
    if gaps:
        print(f"{len(gaps)} test file(s) die under coverage and are NOT in the map:", *gaps, sep="\n  ", flush=True)
    import coverage

    indices = sorted(done)
    broken, seconds = _failing_tests(indices)
    if broken:
        print(f"{len(broken)} tests fail without any mutant and are left out of the map:", *sorted(broken), sep="\n  ")
    cov_map: dict[str, dict[str, list[str]]] = defaultdict(lambda: defaultdict(list))
    old_path = STATE / "coverage_map.json"
    if args.merge and old_path.exists():  # keep what other test files recorded; replace only those re-run here
        rerun = tuple(f"{f}::" for f in files)
        for mod, by_line in json.loads(old_path.read_text()).items():
            shift = _line_shift(mod)  # the modules may have changed since the map was made
            for line, tests in by_line.items():
                if (now := shift.get(int(line))) is not None:
                    cov_map[mod][str(now)] = [t for t in tests if not t.startswith(rerun)]
        old = json.loads((STATE / "durations.json").read_text()) if (STATE / "durations.json").exists() else {}
        seconds = {**{k: v for k, v in old.items() if not k.startswith(rerun)}, **seconds}
    (STATE / "durations.json").write_text(json.dumps(seconds))
    for i in indices:
        data = coverage.CoverageData(basename=str(STATE / f".coverage.{i}"))
        data.read()
        for path in data.measured_files():
            rel = os.path.relpath(path, ROOT)
            for line, ctxs in (data.contexts_by_lineno(path) or {}).items():
                for ctx in ctxs:
                    test = ctx.rsplit("|", 1)[0]
                    if test and test not in broken:
                        cov_map[rel][str(line)].append(test)
    (STATE / "coverage_map.json").write_text(json.dumps(cov_map))
    for mod in cov_map:  # the sources the line numbers refer to, for the next --merge
        if (ROOT / mod).is_file():
            (STATE / "mapped_src" / mod).parent.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(ROOT / mod, STATE / "mapped_src" / mod)
    print(f"coverage map: {len(cov_map)} modules -> {STATE / 'coverage_map.json'}")
    return 1 if failed or gaps else 0


def _line_shift(module: str) -> dict[int, int]:
    """Old line -> current line of `module`, from the source the map was made on (`mapped_src`) to today's; lines
    since deleted or rewritten have none. Without a saved source the map is taken as current."""
    import difflib

    old_path, now_path = STATE / "mapped_src" / module, ROOT / module
    if not now_path.is_file():
        return {}
    now = now_path.read_text().splitlines()
    if not old_path.is_file():
        return {i: i for i in range(1, len(now) + 1)}
    old = old_path.read_text().splitlines()
    shift: dict[int, int] = {}
    for tag, i1, i2, j1, _ in difflib.SequenceMatcher(a=old, b=now, autojunk=False).get_opcodes():
        if tag == "equal":
            shift.update({i1 + k + 1: j1 + k + 1 for k in range(i2 - i1)})
    return shift


def _failing_tests(shards) -> tuple[set[str], dict[str, float]]:
    """Node ids that failed or errored in the unmutated run (they would 'kill' every mutant they reach),
    and every test's seconds, so a mutant runs its fastest tests first."""
    import xml.etree.ElementTree as ET

    out: set[str] = set()
    seconds: dict[str, float] = {}
    for i in shards:
        path = STATE / f"junit.{i}.xml"
        if not path.exists():
            continue
        for case in ET.parse(path).iter("testcase"):
            node = f"{case.get('classname', '').replace('.', '/')}.py::{case.get('name')}"
            seconds[node] = float(case.get("time") or 0.0)
            if case.find("failure") is not None or case.find("error") is not None:
                out.add(node)
    return out, seconds


# ---------------------------------------------------------------- run: mutate and test
def _config(path: Path, modules: list[str], workers: list[str], timeout: float) -> None:
    test_cmd = f"{sys.executable} mutation/pick_tests.py"
    urls = ", ".join(f'"{u}"' for u in workers)
    mods = ", ".join(f'"{m}"' for m in modules)
    dist = f'name = "http"\n\n[cosmic-ray.distributor.http]\nworker-urls = [{urls}]'
    path.write_text(
        f"[cosmic-ray]\nmodule-path = [{mods}]\ntimeout = {timeout}\nexcluded-modules = []\n"
        f'test-command = "{test_cmd}"\n\n[cosmic-ray.distributor]\n{dist}\n'
    )


def _filter(session: Path, sample: int | None, seed: int) -> tuple[int, int]:
    """Skip mutants outside the operator set, on `# pragma: no mutate` lines, or outside a seeded sample."""
    from cosmic_ray.work_db import WorkDB, use_db
    from cosmic_ray.work_item import WorkerOutcome, WorkResult

    keep = re.compile("|".join(f"(?:{o})" for o in OPERATORS))
    skipped = WorkResult(output="outside the operator set or sample", worker_outcome=WorkerOutcome.SKIPPED)
    with use_db(str(session), WorkDB.Mode.open) as db:
        src: dict[str, list[str]] = {}
        out: list[str] = []
        chosen: dict[str, list[tuple]] = defaultdict(list)  # module -> [(operator, occurrence, job id)]
        for item in db.pending_work_items:
            m = item.mutations[0]
            lines = src.setdefault(str(m.module_path), (ROOT / m.module_path).read_text().splitlines())
            if not keep.match(m.operator_name) or PRAGMA in lines[m.start_pos[0] - 1]:
                out.append(item.job_id)
            else:
                chosen[str(m.module_path)].append((m.operator_name, m.occurrence, item.job_id))
        allowed = sum(len(v) for v in chosen.values())
        if sample is not None:  # job ids are random and items come in random order: sort by what names a mutant
            rng = random.Random(seed)
            for module in sorted(chosen):
                ids = sorted(chosen[module])
                out += [job for *_, job in rng.sample(ids, max(0, len(ids) - sample))]
        db.set_multiple_results(out, skipped)  # one transaction
    todo = sum(len(v) if sample is None else min(len(v), sample) for v in chosen.values())
    return todo, allowed


def _free_ports(n: int) -> list[int]:
    """n TCP ports nobody listens on now (another session's workers, a test's toy session, may run beside)."""
    import socket

    socks = [socket.socket() for _ in range(n)]
    try:
        for s in socks:
            s.bind(("localhost", 0))
        return [s.getsockname()[1] for s in socks]
    finally:
        for s in socks:
            s.close()


def _copy_tree(dest: Path) -> None:
    ignore = shutil.ignore_patterns(
        ".venv",
        ".git",
        "runs",
        "build",
        ".devpack",
        ".whl",
        ".caps",
        "__pycache__",
        "*.egg-info",
        "figures",
        "*.sqlite",
        "workers",
    )
    shutil.copytree(ROOT, dest, ignore=ignore, dirs_exist_ok=True)


def cmd_run(args) -> int:
    modules = target_files(args.targets)
    if not modules:
        print("no Python files match the targets; give folders or files under fracture_gs/", file=sys.stderr)
        return 2
    (STATE / "orig").mkdir(parents=True, exist_ok=True)
    for m in modules:
        dest = STATE / "orig" / m
        dest.parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(ROOT / m, dest)
    (STATE / "manifest.json").write_text(json.dumps(modules))
    gaps = json.loads((STATE / "map_gaps.json").read_text()) if (STATE / "map_gaps.json").exists() else []
    if gaps:  # their tests never reach a mutant: what only they would kill counts as survived
        print(f"warning: {len(gaps)} test file(s) are not in the coverage map (they died under it):", *gaps, sep="\n  ")
    session, cfg = STATE / "session.sqlite", STATE / "cosmic-ray.toml"
    if session.exists() and not args.resume:
        session.unlink()
    ports = _free_ports(max(1, args.workers))  # always workers: never mutate this tree
    _config(cfg, modules, [f"http://localhost:{p}" for p in ports], args.timeout)
    cr = [sys.executable, "-m", "cosmic_ray.cli"]
    if not session.exists():
        subprocess.run([*cr, "init", str(cfg), str(session)], cwd=ROOT, check=True)
        todo, allowed = _filter(session, args.sample, args.seed)
        print(f"{len(modules)} modules, {allowed} mutants in the operator set, {todo} to run", flush=True)
    workers = []
    try:
        for i, port in enumerate(ports):
            wdir = STATE / "workers" / f"w{i}"
            _copy_tree(wdir)
            log = open(STATE / f"worker.{i}.log", "w")
            workers.append(
                subprocess.Popen(
                    [*cr, "http-worker", "--port", str(port)],
                    cwd=wdir,
                    stdout=log,
                    stderr=subprocess.STDOUT,
                    start_new_session=True,
                )
            )
        time.sleep(3)
        t0 = time.time()
        try:
            subprocess.run([*cr, "exec", str(cfg), str(session)], cwd=ROOT, check=False, timeout=args.budget)
        except subprocess.TimeoutExpired:
            print(f"stopped after --budget {args.budget:.0f} s; `run --resume` goes on where this left off")
        print(f"executed in {time.time() - t0:.0f} s", flush=True)
    finally:
        for w in workers:
            os.killpg(w.pid, signal.SIGTERM)
    return cmd_report(args)


# ---------------------------------------------------------------- report: score per module, survivors
def _equivalent(mutation, diff: str, equivalents: list[dict]) -> str | None:
    """The reason a surviving mutant changes no behaviour, when `equivalent.toml` gives one.

    An entry names the module, the operator and the exact source line the mutant rewrote (the `-`
    line of its diff), so it follows the line when code above it moves, and a reason a reader can check;
    an optional `mutant` (the `+` line) narrows it to one of several mutants of that operator on that line.
    """
    removed = [ln[1:].strip() for ln in diff.splitlines() if ln.startswith("-") and not ln.startswith("---")]
    added = [ln[1:].strip() for ln in diff.splitlines() if ln.startswith("+") and not ln.startswith("+++")]
    for e in equivalents:
        if (
            e["module"] == str(mutation.module_path)
            and mutation.operator_name.endswith(e["operator"])
            and e["line"].strip() in removed
            and ("mutant" not in e or e["mutant"].strip() in added)
        ):
            return e["reason"]
    return None


def cmd_report(args) -> int:
    from cosmic_ray.work_db import WorkDB, use_db
    from cosmic_ray.work_item import TestOutcome, WorkerOutcome

    rows: dict[str, dict[str, int]] = defaultdict(lambda: defaultdict(int))
    survivors = []
    equivalents = tomllib.loads((HERE / "equivalent.toml").read_text()).get("mutant", [])
    with use_db(str(STATE / "session.sqlite"), WorkDB.Mode.open) as db:
        for item, result in db.completed_work_items:
            m = item.mutations[0]
            if result.worker_outcome == WorkerOutcome.SKIPPED:
                continue
            r = rows[str(m.module_path)]
            if result.worker_outcome != WorkerOutcome.NORMAL:
                r["error"] += 1
            elif result.test_outcome == TestOutcome.SURVIVED and (why := _equivalent(m, result.diff, equivalents)):
                r["equivalent"] += 1
                survivors.append(
                    {
                        "module": str(m.module_path),
                        "line": m.start_pos[0],
                        "operator": m.operator_name,
                        "equivalent": why,
                        "diff": result.diff,
                    }
                )
            elif result.test_outcome == TestOutcome.SURVIVED:
                r["survived"] += 1
                survivors.append(
                    {
                        "module": str(m.module_path),
                        "line": m.start_pos[0],
                        "operator": m.operator_name,
                        "diff": result.diff,
                    }
                )
            else:
                r["killed"] += 1
        pending = db.num_work_items - db.num_results
    total = defaultdict(int)
    keys = ("killed", "survived", "equivalent", "error")
    lines = [f"{'module':<48} {'killed':>7} {'surv.':>6} {'equiv.':>6} {'error':>6} {'score':>6}"]
    for mod in sorted(rows):
        r = rows[mod]
        n = r["killed"] + r["survived"]
        for k in keys:
            total[k] += r[k]
        score = 100 * r["killed"] / max(n, 1)
        cells = " ".join(f"{r[k]:>{7 if k == 'killed' else 6}}" for k in keys)
        lines.append(f"{mod:<48} {cells} {score:>5.1f}%")
    n = total["killed"] + total["survived"]
    score = 100 * total["killed"] / max(n, 1)
    cells = " ".join(f"{total[k]:>{7 if k == 'killed' else 6}}" for k in keys)
    lines.append(f"{'all':<48} {cells} {score:>5.1f}%   ({pending} pending)")
    print("\n".join(lines))
    (STATE / "report.txt").write_text("\n".join(lines) + "\n")
    (STATE / "survivors.json").write_text(json.dumps(survivors, indent=1))
    return 0


# ---------------------------------------------------------------- retest: the survivors against today's tests
def cmd_retest(args) -> int:
    """Run a session's survivors again against the current tests (after writing the tests that kill them). The
    session is kept as `session_before.sqlite`; mutants never reached are marked skipped; modules changed since the
    session was made (`--since COMMIT`) are left as they were, since a mutant is named by its occurrence in the
    module as it was."""
    from cosmic_ray.work_db import WorkDB, WorkResultStorage, use_db
    from cosmic_ray.work_item import TestOutcome, WorkerOutcome, WorkResult

    session = STATE / "session.sqlite"
    if not (STATE / "session_before.sqlite").exists():
        shutil.copyfile(session, STATE / "session_before.sqlite")
    changed: set[str] = set()
    if args.since:
        diff = subprocess.run(
            ["git", "diff", "--name-only", args.since, "HEAD", "--", "fracture_gs"],
            cwd=ROOT,
            capture_output=True,
            text=True,
            check=True,
        ).stdout
        changed = set(diff.split())
    equivalents = tomllib.loads((HERE / "equivalent.toml").read_text()).get("mutant", [])
    never = WorkResult(output="not reached in the session", worker_outcome=WorkerOutcome.SKIPPED)
    again, modules = [], set()
    with use_db(str(session), WorkDB.Mode.open) as db:
        for item in db.pending_work_items:
            db.set_result(item.job_id, never)
        for item, result in db.completed_work_items:
            m = item.mutations[0]
            if (
                result.worker_outcome == WorkerOutcome.NORMAL
                and result.test_outcome == TestOutcome.SURVIVED
                and str(m.module_path) not in changed
                and not _equivalent(m, result.diff or "", equivalents)
            ):
                again.append(item.job_id)
                modules.add(str(m.module_path))
        with db._session_maker.begin() as s:
            s.query(WorkResultStorage).filter(WorkResultStorage.job_id.in_(again)).delete()
    print(f"{len(again)} survivors in {len(modules)} modules run again", flush=True)
    args.targets, args.resume, args.sample, args.seed = sorted(modules), True, None, 0
    return cmd_run(args)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="cmd", required=True)
    m = sub.add_parser("map", help="record which test executes which line (coverage contexts)")
    m.add_argument("--jobs", type=int, default=os.cpu_count() or 1, help="parallel pytest shards")
    m.add_argument("--tests", default="test_*.py", help="globs of test files under tests/, comma-separated")
    m.add_argument("--merge", action="store_true", help="add to the existing map instead of replacing it")
    m.add_argument("pytest_args", nargs="*", help="extra pytest arguments, e.g. -m 'not slow'")
    r = sub.add_parser("run", help="mutate the targets and run the tests that reach each mutant")
    r.add_argument("targets", nargs="*", help=f"folders, files or globs (default: {' '.join(DEFAULT_TARGETS)})")
    r.add_argument("--workers", type=int, default=1, help="parallel HTTP workers, one copy of the tree each")
    r.add_argument("--sample", type=int, default=None, help="at most this many mutants per module (seeded)")
    r.add_argument("--seed", type=int, default=0, help="seed of the sample")
    r.add_argument("--timeout", type=float, default=600.0, help="seconds one mutant's tests may take")
    r.add_argument("--budget", type=float, default=None, help="stop executing after this many seconds")
    r.add_argument("--resume", action="store_true", help="continue the existing session instead of a new one")
    t = sub.add_parser("retest", help="run the session's survivors again against the current tests")
    t.add_argument("--workers", type=int, default=1, help="parallel HTTP workers, one copy of the tree each")
    t.add_argument("--timeout", type=float, default=600.0, help="seconds one mutant's tests may take")
    t.add_argument("--budget", type=float, default=None, help="stop executing after this many seconds")
    t.add_argument("--since", default=None, help="the commit the session was made on: modules changed since stay")
    sub.add_parser("report", help="score per module and the survivors (mutation/.state/survivors.json)")
    # score = killed / (killed + survived); equivalent mutants (equivalent.toml, each with its reason) are left out
    args = ap.parse_args(argv)
    return {"map": cmd_map, "run": cmd_run, "retest": cmd_retest, "report": cmd_report}[args.cmd](args)


if __name__ == "__main__":
    sys.exit(main())
