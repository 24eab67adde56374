"""The torture suite's engine: runs one case (one or more rodfab invocations) in a fresh folder, under a
memory cap and a timeout, and checks what the reliability issue asks of every hostile input:

  - the exit code is in the expected set, and the process did not die by a signal (crash) or hang;
  - a failure comes with a located message on stderr (the file or the option named);
  - the folder holds exactly what is allowed afterwards: the inputs byte-identical (checksums), the
    declared outputs of successful steps and nothing else (no hidden staging, no *.tmp*), and the
    private TMPDIR empty;
  - optional: a peak resident memory limit, warnings on success, `rodfab inspect` OK for written jobs.

Standard library only (Debian 12's python3 3.11)."""

from __future__ import annotations

import dataclasses
import fnmatch
import hashlib
import os
import re
import resource
import shutil
import signal as sig
import stat
import subprocess
import tempfile
import time
from pathlib import Path
from typing import Callable, Iterable, Optional, Union

MiB = 1 << 20
GiB = 1 << 30


def _env_float(name: str, default: float) -> float:
    try:
        return float(os.environ.get(name, default))
    except ValueError:
        return default


# The address-space cap for every rodfab process (RLIMIT_AS). AddressSanitizer reserves terabytes of
# shadow memory, so a sanitizer build runs without the cap and a watchdog kills it when its resident
# memory passes SANITIZER_RSS_FACTOR times the cap instead.
MEMORY_CAP = int(_env_float("TORTURE_MEMORY_CAP", 2 * GiB))
SANITIZER_RSS_FACTOR = 3
# The budget handed to rodfab with --max-memory where a case asks for it, and the peak resident memory
# such a run may reach: the budget plus a fixed allowance for the runtime and shared libraries.
MAX_MEMORY = os.environ.get("TORTURE_MAX_MEMORY", "512M")


def _bytes(size: str) -> int:
    """"512M", "2G", "300000000" -> bytes (binary suffixes K, M, G)."""
    m = re.fullmatch(r"\s*([0-9.]+)\s*([KMG]?)i?B?\s*", size, re.IGNORECASE)
    if not m:
        raise SystemExit(f"TORTURE_MAX_MEMORY: expected a size like 512M, got {size!r}")
    return int(float(m.group(1)) * {"": 1, "K": 1 << 10, "M": 1 << 20, "G": 1 << 30}[m.group(2).upper()])


MAX_MEMORY_BYTES = _bytes(MAX_MEMORY)
RSS_ALLOWANCE = 64 * MiB
# How long a process may take to exit once it has been sent SIGINT/SIGTERM (the issue: "within 1 s").
SIGNAL_GRACE = _env_float("TORTURE_SIGNAL_GRACE", 1.0)
# CPU seconds after a signal beyond which the watchdog's exit is a defect (its grace is 0.6 s of wall time).
WATCHDOG_CPU = 0.45
# Multiplies every timeout (slow machines, sanitizer builds).
TIME_SCALE = _env_float("TORTURE_TIME_SCALE", 1.0)
# Seconds from start within which the process may still be in the dynamic loader (before its handlers exist).
LOADER_WINDOW = 1.0

# C++ library exceptions that leak out unexplained: never a message about the input, whatever it names.
INTERNAL_ERRORS = (r"std::bad_alloc|std::length_error|terminate called|basic_filebuf::|basic_string::|vector::_M_|"
                   r"map::at|\bstoi\b|\bstod\b|Segmentation fault")

Content = Union[str, bytes, Callable[[Path, "Context"], None]]


@dataclasses.dataclass(frozen=True)
class Fraction:
    """A signal delay given as a fraction of the case's first step's duration (an uninterrupted run of
    the same work), so that random delays spread over the whole run on any machine."""
    of_first_step: float
    at_least: float = 0.0


@dataclasses.dataclass
class Step:
    """One rodfab invocation.

    argv      arguments after `rodfab`; "{src}" is replaced by the source folder, "{examples}" by its
              examples folder.
    expect    allowed exit codes when no signal was sent (0 success, 1 bad input, 2 bad command line).
    where     on a non-zero exit, stderr must contain at least one of these (the file, entry or option
              the message is about): the "located message".
    patterns  on a non-zero exit, stderr must also match every one of these regular expressions
              (case-insensitive).
    warnings  on exit 0, stderr must match every one of these regular expressions (case-insensitive).
    outputs   paths (relative to the case folder) the step creates when it exits 0; they must then exist
              and must not exist after a failure. A directory output covers everything beneath it.
    jobs      outputs that are print jobs: `rodfab inspect` must pass them when the step exits 0.
    replaces  inputs the step may change when it exits 0 (--force over an old job).
    signal    (signal number, trigger): the trigger is a delay in seconds or a predicate on the case
              folder polled every few milliseconds; once it fires while the process still runs, the
              signal is sent and the process must exit within SIGNAL_GRACE with 128 + signal (or 0 if it
              had already finished its work: outputs complete). SIGKILL steps are expected to die;
              they set the stage for the next step.
    max_memory  pass --max-memory MAX_MEMORY and require peak resident memory within it.
    rss_limit   peak resident memory limit in bytes (None: only the address-space cap).
    timeout   seconds before the process counts as hung (scaled by TORTURE_TIME_SCALE).
    background, start_when  run concurrently with the following steps (two rodfab runs in one folder).
    """
    argv: list[str]
    expect: set[int] = dataclasses.field(default_factory=lambda: {0})
    where: list[str] = dataclasses.field(default_factory=list)
    patterns: list[str] = dataclasses.field(default_factory=list)
    warnings: list[str] = dataclasses.field(default_factory=list)
    outputs: list[str] = dataclasses.field(default_factory=list)
    jobs: list[str] = dataclasses.field(default_factory=list)
    replaces: list[str] = dataclasses.field(default_factory=list)
    signal: Optional[tuple[int, Union[float, Fraction, Callable[[Path], bool]]]] = None
    background: bool = False      # start it and go on with the next steps; checked at the end
    start_when: Optional[Callable[[Path], bool]] = None  # a background step's next step waits for this
    max_memory: bool = False
    rss_limit: Optional[int] = None
    timeout: float = 30.0


@dataclasses.dataclass
class Case:
    name: str
    steps: list[Step]
    files: dict[str, Content] = dataclasses.field(default_factory=dict)
    note: str = ""          # what the case is about, printed with a failure
    group: str = ""         # the class (set by the runner from the module)


class Context:
    """What a case's file builders and triggers may use: the binary, the source folder, a cache."""

    def __init__(self, rodfab: Path, src: Path, sanitized: bool):
        self.rodfab, self.src, self.sanitized = rodfab, src, sanitized
        self.cache_dir = Path(tempfile.mkdtemp(prefix="rodfab-torture-cache-"))
        self._cache: dict[str, Path] = {}

    def cached(self, key: str, build: Callable[[Path], None]) -> Path:
        """A file or folder built once per run (e.g. a valid job to tamper with) and copied per case."""
        if key not in self._cache:
            path = self.cache_dir / key
            build(path)
            self._cache[key] = path
        return self._cache[key]

    def run_rodfab(self, argv: list[str], cwd: Path, timeout: float = 120) -> subprocess.CompletedProcess:
        """Runs rodfab for a fixture (not a checked step); fails loudly when the fixture cannot be made."""
        r = subprocess.run([str(self.rodfab), *argv], cwd=cwd, capture_output=True, timeout=timeout * TIME_SCALE,
                           stdin=subprocess.DEVNULL, env=child_env(cwd), preexec_fn=self.limits)
        if r.returncode != 0:
            raise RuntimeError(f"fixture: rodfab {' '.join(argv)} failed ({r.returncode}): {r.stderr.decode(errors='replace')}")
        return r

    def limits(self) -> None:
        if not self.sanitized:
            resource.setrlimit(resource.RLIMIT_AS, (MEMORY_CAP, MEMORY_CAP))
        resource.setrlimit(resource.RLIMIT_CORE, (0, 0))

    def close(self) -> None:
        shutil.rmtree(self.cache_dir, ignore_errors=True)


def child_env(tmpdir: Path) -> dict[str, str]:
    env = dict(os.environ)
    env["TMPDIR"] = str(tmpdir)
    # glibc reserves 64 MiB of address space per malloc arena and thread; on a many-core machine that
    # alone would exhaust the address-space cap. Two arenas keep the cap about the program's own needs.
    env["MALLOC_ARENA_MAX"] = "2"
    env.setdefault("ASAN_OPTIONS", "detect_leaks=0:allocator_may_return_null=0")
    env["LC_ALL"] = "C"
    return env


def is_sanitized(binary: Path) -> bool:
    data = binary.read_bytes()
    return b"__asan_init" in data or b"__tsan_init" in data or b"__msan_init" in data


# --- snapshots of a folder --------------------------------------------------------------------------------

def _digest(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def snapshot(root: Path) -> dict[str, str]:
    """Every entry under root (hidden ones too) -> its kind and content: files by checksum, links by
    target. FIFOs and devices are recorded by kind only (never opened)."""
    out: dict[str, str] = {}
    for dirpath, dirnames, filenames in os.walk(root, followlinks=False):
        for name in dirnames + filenames:
            p = Path(dirpath) / name
            rel = str(p.relative_to(root))
            st = os.lstat(p)
            if stat.S_ISLNK(st.st_mode):
                out[rel] = "link:" + os.readlink(p)
            elif stat.S_ISDIR(st.st_mode):
                out[rel] = "dir"
            elif stat.S_ISREG(st.st_mode):
                out[rel] = "file:" + _digest(p)
            elif stat.S_ISFIFO(st.st_mode):
                out[rel] = "fifo"
            else:
                out[rel] = "special"
    return out


def _covered(rel: str, outputs: Iterable[str]) -> bool:
    for o in outputs:
        o = o.rstrip("/")
        if rel == o or rel.startswith(o + "/") or fnmatch.fnmatchcase(rel, o):
            return True
    return False


# --- running one process --------------------------------------------------------------------------------

@dataclasses.dataclass
class Outcome:
    code: Optional[int] = None       # exit status, or None when killed by a signal
    signal: Optional[int] = None     # the signal that killed it
    hung: bool = False               # killed by us after the timeout
    memory_killed: bool = False      # killed by the sanitizer-build memory watchdog
    sent: Optional[int] = None       # the signal we sent, if any
    sent_after: Optional[float] = None   # seconds from start to our signal
    exit_after_signal: Optional[float] = None
    cpu_after_signal: float = 0.0    # CPU seconds (all threads) the process used after our signal
    done_at_signal: bool = False     # the step's outputs were all in place when the signal was sent
    late: bool = False               # did not exit within SIGNAL_GRACE after our signal
    peak_rss: int = 0                # bytes
    seconds: float = 0.0
    stdout: str = ""
    stderr: str = ""

    def describe(self) -> str:
        if self.hung:
            return f"hung (killed after {self.seconds:.1f} s)"
        if self.memory_killed:
            return f"killed by the memory watchdog at {self.peak_rss / MiB:.0f} MiB resident"
        if self.signal is not None:
            return f"killed by {sig.Signals(self.signal).name}"
        return f"exit {self.code}"


def _cpu_seconds(pid: int) -> float:
    """User + system CPU time of a running process (all its threads) from /proc/PID/stat."""
    try:
        with open(f"/proc/{pid}/stat") as f:
            fields = f.read().rsplit(")", 1)[1].split()
        return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")
    except (OSError, IndexError, ValueError):
        return 0.0


def _threads(pid: int) -> int:
    try:
        with open(f"/proc/{pid}/status") as f:
            for line in f:
                if line.startswith("Threads:"):
                    return int(line.split()[1])
    except (OSError, ValueError):
        pass
    return 1


def _rss(pid: int) -> int:
    try:
        with open(f"/proc/{pid}/status") as f:
            for line in f:
                if line.startswith("VmRSS:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    return 0


class Running:
    """One rodfab process being watched: the signal trigger, the grace after a signal, the timeout and
    (sanitizer builds) the resident-memory watchdog. poll() returns True once it has been reaped."""

    def __init__(self, ctx: Context, argv: list[str], cwd: Path, tmpdir: Path, step: Step, first: float, tag: str):
        self.ctx, self.cwd, self.step = ctx, cwd, step
        self.out = Outcome()
        self.stdout_path, self.stderr_path = tmpdir.parent / f"stdout-{tag}", tmpdir.parent / f"stderr-{tag}"
        # stdin is a pipe that stays open and silent: a program that reads /dev/stdin hangs visibly.
        stdin_r, self.stdin_w = os.pipe()
        self.start = time.monotonic()
        with open(self.stdout_path, "wb") as so, open(self.stderr_path, "wb") as se:
            self.proc = subprocess.Popen([str(ctx.rodfab), *argv], cwd=cwd, stdin=stdin_r, stdout=so, stderr=se,
                                         env=child_env(tmpdir), preexec_fn=ctx.limits, start_new_session=True)
        os.close(stdin_r)
        self.timeout = step.timeout * TIME_SCALE
        self.signum, self.trigger = step.signal if step.signal else (None, None)
        if isinstance(self.trigger, Fraction):
            self.trigger = max(self.trigger.at_least, self.trigger.of_first_step * first)
        self.sent_at: Optional[float] = None
        self.cpu_at_signal = 0.0
        self.parallelism = 1
        self.status: Optional[int] = None
        self.rusage = None

    def _kill_and_reap(self) -> None:
        os.kill(self.proc.pid, sig.SIGKILL)
        _, self.status, self.rusage = os.wait4(self.proc.pid, 0)

    def poll(self) -> bool:
        if self.status is not None:
            return True
        pid, st, ru = os.wait4(self.proc.pid, os.WNOHANG)
        if pid:
            self.status, self.rusage = st, ru
            return True
        out, now = self.out, time.monotonic() - self.start
        if self.signum is not None and self.sent_at is None:
            fire = (now >= self.trigger) if isinstance(self.trigger, (int, float)) else _safe(self.trigger, self.cwd)
            if fire:
                self.cpu_at_signal = _cpu_seconds(self.proc.pid)
                self.parallelism = max(1, min(_threads(self.proc.pid), os.cpu_count() or 1))
                os.kill(self.proc.pid, self.signum)
                self.sent_at = time.monotonic()
                # Were its outputs in place (renamed into place: complete) when the signal came? Only
                # then may it still exit 0: the work was done. Looked at after the kill, not before:
                # the signal arrives at the kill or later, and a short job (a small simulate output)
                # can commit and finish between a look before the kill and the kill itself (a CI run
                # failed so: exit 0, 20 ms after a signal sent "before" the output existed).
                out.done_at_signal = bool(self.step.outputs) and all((self.cwd / o).exists() for o in self.step.outputs)
                out.sent, out.sent_after = self.signum, self.sent_at - self.start
        if self.sent_at is not None and self.signum != sig.SIGKILL:
            if time.monotonic() - self.sent_at > SIGNAL_GRACE * TIME_SCALE + 4.0:
                out.hung = True
                self._kill_and_reap()
                return True
        if self.ctx.sanitized and _rss(self.proc.pid) > SANITIZER_RSS_FACTOR * MEMORY_CAP:
            out.memory_killed = True
            self._kill_and_reap()
            return True
        if now > self.timeout:
            out.hung = True
            self._kill_and_reap()
            return True
        return False

    def wait(self) -> Outcome:
        while not self.poll():
            time.sleep(0.004)
        return self.finish()

    def finish(self) -> Outcome:
        out = self.out
        os.close(self.stdin_w)
        self.proc.returncode = 0  # reaped above; keeps Popen from waiting again
        out.seconds = time.monotonic() - self.start
        if self.sent_at is not None:
            out.exit_after_signal = time.monotonic() - self.sent_at
            cpu = (self.rusage.ru_utime + self.rusage.ru_stime) if self.rusage else 0.0
            out.cpu_after_signal = max(0.0, cpu - self.cpu_at_signal)
            # Late: more than the grace in wall-clock time and in CPU time per core it could use (its
            # threads, at most the machine's cores): what the wall clock would say on an idle machine, so
            # that a busy shared machine does not make a prompt program look slow. One that blocks
            # instead of exiting is caught by the kill SIGNAL_GRACE + 4 s after the signal.
            grace = SIGNAL_GRACE * TIME_SCALE
            out.late = out.exit_after_signal > grace and (out.cpu_after_signal / self.parallelism > grace or out.hung)
        out.peak_rss = self.rusage.ru_maxrss * 1024 if self.rusage else 0
        if os.WIFSIGNALED(self.status):
            out.signal = os.WTERMSIG(self.status)
        else:
            out.code = os.WEXITSTATUS(self.status)
        out.stdout = self.stdout_path.read_text(errors="replace")
        out.stderr = self.stderr_path.read_text(errors="replace")
        return out


def _wait_for(predicate: Optional[Callable[[Path], bool]], folder: Path, running: Running) -> None:
    """Lets a background step get going: until the predicate holds (or it exits; at most 30 s)."""
    deadline = time.monotonic() + 30 * TIME_SCALE
    while predicate is not None and time.monotonic() < deadline and not running.poll():
        if _safe(predicate, folder):
            return
        time.sleep(0.004)


def _safe(predicate: Callable[[Path], bool], folder: Path) -> bool:
    try:
        return bool(predicate(folder))
    except OSError:
        return False


# --- running and checking one case ---------------------------------------------------------------------

def expand(argv: list[str], ctx: Context) -> list[str]:
    return [a.replace("{src}", str(ctx.src)).replace("{examples}", str(ctx.src / "examples")) for a in argv]


def build_files(files: dict[str, Content], root: Path, ctx: Context) -> None:
    for name, content in files.items():
        path = root / name
        path.parent.mkdir(parents=True, exist_ok=True)
        if callable(content):
            content(path, ctx)
        elif isinstance(content, bytes):
            path.write_bytes(content)
        else:
            path.write_text(content)


def _excerpt(text: str, lines: int = 6) -> str:
    rows = [r for r in text.strip().splitlines() if r.strip()]
    if len(rows) > lines:
        rows = rows[:lines - 1] + [f"... ({len(rows) - lines + 1} more lines)"]
    return " | ".join(r[:220] for r in rows) or "(empty)"


def check_step(ctx: Context, step: Step, o: Outcome, cwd: Path) -> list[str]:
    problems: list[str] = []
    if o.hung and o.sent is not None:
        problems.append(f"{sig.Signals(o.sent).name} ignored: still running {o.exit_after_signal:.1f} s after it "
                        f"({o.seconds:.1f} s in all, peak RSS {o.peak_rss / MiB:.0f} MiB); killed")
        return problems
    if o.hung:
        problems.append(f"{o.describe()}; peak RSS {o.peak_rss / MiB:.0f} MiB")
        return problems
    if o.memory_killed:
        problems.append(o.describe())
        return problems
    if o.sent == sig.SIGKILL:
        return problems  # the stage for the next step
    if step.signal and step.signal[0] == sig.SIGKILL:
        problems.append(f"inconclusive: the run ended ({o.describe()}) before the moment for SIGKILL came")
        return problems
    if step.signal and o.sent is None and callable(step.signal[1]):
        # A moment named by what appears on disk must come, or the case tests nothing.
        problems.append(f"inconclusive: the run ended ({o.describe()}) before the moment for "
                        f"{sig.Signals(step.signal[0]).name} came")
        return problems
    if o.sent is not None:
        wanted = 128 + o.sent
        if o.late:
            problems.append(f"{sig.Signals(o.sent).name} not honoured: exited {o.exit_after_signal:.1f} s after it, having "
                            f"used {o.cpu_after_signal:.1f} s of CPU meanwhile (allowed {SIGNAL_GRACE * TIME_SCALE:.1f} s "
                            f"per core in use), {o.describe()}")
        # The watchdog's exit (common/interrupt.hpp) keeps the promise but means the work did not poll for
        # 0.6 s: a step that can work that long without looking (simulate's solves did) is a defect. Only
        # when it had the CPU to notice: on a loaded machine a short unpolled step (writing a grid) can
        # outlast the grace in wall-clock time alone.
        if "did not stop within the grace time" in o.stderr and o.cpu_after_signal > WATCHDOG_CPU * TIME_SCALE:
            problems.append(f"{sig.Signals(o.sent).name} at {o.sent_after:.2f} s was not noticed by the work: the watchdog "
                            f"ended it after {o.cpu_after_signal:.2f} s of CPU ({_excerpt(o.stderr)})")
        # Before main, while the dynamic loader maps ~80 libraries, the signal's default action ends the
        # process: nothing is written yet and a shell reports the same 128 + N (the leftover check still runs).
        in_loader = o.signal == o.sent and o.sent_after <= LOADER_WINDOW * TIME_SCALE
        if in_loader:
            pass
        elif o.signal is not None:
            problems.append(f"died by {sig.Signals(o.signal).name} after {sig.Signals(o.sent).name} "
                            f"at {o.sent_after:.2f} s (expected exit {wanted})")
        elif o.code == 0 and not o.done_at_signal:
            problems.append(f"exit 0 after {sig.Signals(o.sent).name} (sent at {o.sent_after:.2f} s, before its outputs "
                            f"were in place): the signal was ignored, expected exit {wanted} and nothing written")
        elif o.code not in (wanted, 0):
            problems.append(f"exit {o.code} after {sig.Signals(o.sent).name}, expected {wanted}: {_excerpt(o.stderr)}")
    else:
        if o.signal is not None:
            problems.append(f"crashed: {o.describe()} after {o.seconds:.1f} s; peak RSS {o.peak_rss / MiB:.0f} MiB; "
                            f"stderr: {_excerpt(o.stderr)}")
        elif o.code not in step.expect:
            problems.append(f"exit {o.code}, expected {sorted(step.expect)}; stderr: {_excerpt(o.stderr)}")
    report = re.search(r"ERROR: \w*Sanitizer|runtime error:", o.stderr)
    if report:
        problems.append(f"sanitizer report: {_excerpt(o.stderr[report.start():], 3)}")
    if step.max_memory and o.code == 2 and "--max-memory" in o.stderr:
        problems.append(f"--max-memory {MAX_MEMORY} refused: {_excerpt(o.stderr, 2)}")
        return problems
    if o.code not in (None, 0) and o.sent is None:
        internal = re.search(INTERNAL_ERRORS, o.stderr)
        if internal:
            problems.append(f"an internal error, not a message about the input ({internal.group(0)!r}): {_excerpt(o.stderr)}")
        if o.code not in step.expect:
            pass  # the exit code is the failure; its message was shown with it
        elif step.where and not any(w in o.stderr for w in step.where):
            problems.append(f"message not located (names none of {step.where}): {_excerpt(o.stderr)}")
        for p in step.patterns if o.code in step.expect else []:
            if not re.search(p, o.stderr, re.IGNORECASE):
                problems.append(f"message lacks /{p}/: {_excerpt(o.stderr)}")
    if o.code == 0 and o.sent is None:
        for p in step.warnings:
            if not re.search(p, o.stderr, re.IGNORECASE):
                problems.append(f"no warning /{p}/ on stderr: {_excerpt(o.stderr)}")
    limit = step.rss_limit
    if step.max_memory:
        limit = min(limit or MAX_MEMORY_BYTES + RSS_ALLOWANCE, MAX_MEMORY_BYTES + RSS_ALLOWANCE)
    if limit and o.peak_rss > limit and not ctx.sanitized:
        problems.append(f"peak resident memory {o.peak_rss / MiB:.0f} MiB > {limit / MiB:.0f} MiB")
    if o.code == 0:
        for job in step.jobs:
            if not (cwd / job).exists():
                continue  # reported as a missing output
            r = subprocess.run([str(ctx.rodfab), "inspect", job], cwd=cwd, capture_output=True, text=True,
                               timeout=120 * TIME_SCALE, stdin=subprocess.DEVNULL, env=child_env(cwd.parent / "tmp"),
                               preexec_fn=ctx.limits)
            if r.returncode != 0 or "verdict:       OK" not in r.stdout:
                problems.append(f"rodfab inspect {job}: exit {r.returncode}: {_excerpt(r.stderr)}")
    return problems


def check_folder(before: dict[str, str], after: dict[str, str], allowed: set[str], required: set[str],
                 replaceable: set[str]) -> list[str]:
    problems: list[str] = []
    for rel, kind in before.items():
        if _covered(rel, replaceable):
            continue
        if rel not in after:
            problems.append(f"input {rel} was removed")
        elif after[rel] != kind:
            problems.append(f"input {rel} was changed")
    extra = sorted(rel for rel in after if rel not in before and not _covered(rel, allowed))
    # Report top-level leftovers only (a leftover folder's content is implied).
    tops = [rel for rel in extra if not any(rel.startswith(e + "/") for e in extra if e != rel)]
    if tops:
        problems.append("left behind: " + ", ".join(tops[:8]) + (f" (+{len(tops) - 8} more)" if len(tops) > 8 else ""))
    for rel in sorted(required):
        if rel not in after:
            problems.append(f"output {rel} missing after success")
    return problems


def run_case(ctx: Context, case: Case, keep: bool = False) -> tuple[list[str], list[str]]:
    """Returns (problems, log lines)."""
    base = Path(tempfile.mkdtemp(prefix=f"rodfab-torture-{case.name}-"))
    cwd, tmpdir = base / "work", base / "tmp"
    cwd.mkdir()
    tmpdir.mkdir()
    log: list[str] = []
    problems: list[str] = []
    try:
        build_files(case.files, cwd, ctx)
        before = snapshot(cwd)
        allowed: set[str] = set()
        required: set[str] = set()
        replaceable: set[str] = set()
        first = 0.0
        background: list[tuple[int, Step, list[str], Running]] = []

        def record(n: int, step: Step, argv: list[str], o: Outcome) -> None:
            sent = f" ({sig.Signals(o.sent).name} sent at {o.sent_after:.2f} s)" if o.sent else \
                (" (finished before the signal's moment)" if step.signal else "")
            bg = " [background]" if step.background else ""
            log.append(f"  step {n + 1}{bg}: rodfab {' '.join(argv)}{sent} -> {o.describe()} after {o.seconds:.2f} s, "
                       f"peak RSS {o.peak_rss / MiB:.0f} MiB")
            problems.extend(f"step {n + 1}: {p}" for p in check_step(ctx, step, o, cwd))
            if o.code == 0:
                allowed.update(step.outputs)
                required.update(step.outputs)
                replaceable.update(step.replaces)

        for n, step in enumerate(case.steps):
            argv = expand(step.argv, ctx) + (["--max-memory", MAX_MEMORY] if step.max_memory else [])
            step = dataclasses.replace(step, where=[w.replace("{cwd}", str(cwd)) for w in step.where])
            running = Running(ctx, argv, cwd, tmpdir, step, first, str(n))
            if step.background:
                background.append((n, step, argv, running))
                _wait_for(step.start_when, cwd, running)
                continue
            while not running.poll():  # the background steps are watched meanwhile
                for _, _, _, b in background:
                    b.poll()
                time.sleep(0.004)
            o = running.finish()
            if n == 0:
                first = o.seconds
            record(n, step, argv, o)
            if any("inconclusive:" in p for p in problems):
                break
        for n, step, argv, running in background:
            record(n, step, argv, running.wait())
        if any("inconclusive:" in p for p in problems):
            # A moment that never came leaves what the uninterrupted run made (its output, which the
            # later steps never see): nothing else about this attempt says anything.
            return [p for p in problems if "inconclusive:" in p], log
        after = snapshot(cwd)
        problems += check_folder(before, after, allowed, required, replaceable)
        left = sorted(os.listdir(tmpdir))
        if left:
            problems.append("left behind in TMPDIR: " + ", ".join(left[:8]))
    except Exception as e:  # a broken fixture is a failure of the case, reported as such
        problems.append(f"harness error: {type(e).__name__}: {e}")
    finally:
        if keep:
            log.append(f"  kept: {base}")
        else:
            _rmtree(base)
    return problems, log


def _rmtree(path: Path) -> None:
    def onerror(func, p, exc):  # read-only leftovers: make writable and retry
        try:
            os.chmod(p, 0o700)
            func(p)
        except OSError:
            pass
    for dirpath, dirnames, _ in os.walk(path):
        for d in dirnames:
            try:
                os.chmod(os.path.join(dirpath, d), 0o700)
            except OSError:
                pass
    shutil.rmtree(path, onerror=onerror)
