"""Run the bench's remaining groups unattended, committing finished cells as they land.

    python tools/bench_unattended.py [--queue benchmarks/grid_queue.txt] [--commit-every 1800] [--document BENCHMARKS.md]
                                     [--dry-run]
    make bench-grid          # the same, in the background: setsid nohup ... > runs/bench-grid.log

Each non-blank, non-comment line of the queue holds the options of one ``xted bench`` run, most
informative first; the queue is read again before each run, so a line added or moved meanwhile is
taken up without a restart. The bench skips every cell already stored under its current key, so the runner can
be killed at any point and restarted: it loses at most the group of seeds in flight. New result
files under ``benchmarks/results/bench`` and the priors the bench trained (exported to
``benchmarks/results/priors``, which a fresh checkout restores instead of training again) are
committed (only they) when a run ends and, while one runs, whenever ``--commit-every`` seconds have
passed since the last commit. With them go the ``--document`` files (BENCHMARKS.md by default): their
report blocks are rewritten from the store first (``xted bench refresh``), unless a document has
uncommitted changes of its own, which are never committed by the runner.
"""

from __future__ import annotations

import argparse
import shlex
import signal
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
STORE = "benchmarks/results/bench"
KEPT_PRIORS = "benchmarks/results/priors"  # the bench's exported copies of the priors it trained
XTED = Path(sys.executable).with_name("xted")


def queue_lines(path: Path) -> list[list[str]]:
    lines = [line.strip() for line in path.read_text().splitlines()]
    return [shlex.split(line) for line in lines if line and not line.startswith("#")]


def refreshed_documents(documents: list[str]) -> list[str]:
    """Rewrite the report blocks of those documents that have no uncommitted changes; the documents rewritten."""
    unedited = [document for document in documents if (ROOT / document).is_file() and subprocess.run(
        ["git", "diff", "--quiet", "HEAD", "--", document], cwd=ROOT, check=False).returncode == 0]
    if not unedited:
        return []
    done = subprocess.run([str(XTED), "bench", "refresh", *unedited], cwd=ROOT, check=False)
    return unedited if done.returncode == 0 else []


def commit_results(reason: str, documents: list[str]) -> bool:
    """Commit new or changed files under the store and the kept priors, with the documents' report blocks
    refreshed from them; True where a commit was made."""
    paths = [path for path in (STORE, KEPT_PRIORS) if (ROOT / path).exists()]
    status = subprocess.run(["git", "status", "--porcelain", "--", *paths], cwd=ROOT, capture_output=True, text=True)
    if not status.stdout.strip():
        return False
    count = len(status.stdout.strip().splitlines())
    paths += refreshed_documents(documents)
    subprocess.run(["git", "add", "--", *paths], cwd=ROOT, check=False)
    done = subprocess.run(["git", "commit", "-q", "-m", f"bench results: {count} files ({reason}; tools/bench_unattended.py)",
                           "--", *paths], cwd=ROOT, check=False)
    return done.returncode == 0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--queue", type=Path, default=ROOT / "benchmarks" / "grid_queue.txt")
    parser.add_argument("--commit-every", type=float, default=1800.0, help="Seconds between commits during a run.")
    parser.add_argument("--document", action="append", default=None,
                        help="A markdown file (repository-relative) whose report blocks are refreshed and committed with "
                        "the results (repeatable; default BENCHMARKS.md).")
    parser.add_argument("--dry-run", action="store_true", help="Print the bench commands and exit.")
    args = parser.parse_args()
    runs = queue_lines(args.queue)
    documents = args.document if args.document is not None else ["BENCHMARKS.md"]
    if args.dry_run:
        for options in runs:
            print(shlex.join([str(XTED), "bench", "run", *options]))
        return

    stopping = False

    def stop(signum, frame):  # noqa: ARG001 - signal handler signature
        nonlocal stopping
        stopping = True

    signal.signal(signal.SIGTERM, stop)
    last_commit = time.monotonic()
    finished: set[str] = set()
    while True:  # the queue is read again before every run: lines edited meanwhile take effect
        pending = [options for options in queue_lines(args.queue) if shlex.join(options) not in finished]
        if not pending:
            break
        options = pending[0]
        number = len(finished) + 1
        print(f"[{time.strftime('%H:%M:%S')}] run {number} ({len(pending) - 1} more queued): "
              f"xted bench run {shlex.join(options)}", flush=True)
        process = subprocess.Popen([str(XTED), "bench", "run", *options], cwd=ROOT)
        while process.poll() is None:
            time.sleep(10)
            if stopping:
                process.terminate()
                process.wait()
                break
            if time.monotonic() - last_commit >= args.commit_every:
                commit_results("periodic", documents)
                last_commit = time.monotonic()
        commit_results(f"run {number} ended", documents)
        last_commit = time.monotonic()
        finished.add(shlex.join(options))
        if stopping:
            print("stopped: finished cells are committed; rerun to go on", flush=True)
            return
    print(f"[{time.strftime('%H:%M:%S')}] the queue is done", flush=True)


if __name__ == "__main__":
    main()
