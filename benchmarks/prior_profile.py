"""Where a prior train step spends its time on the CPU: XLA's per-operation trace, grouped.

    python benchmarks/prior_profile.py --target halfcheetah-medium-replay [--preset cpu] [--steps 20]
        [--set F=V ...] [--top 12]

Runs ``steps`` train steps under ``jax.profiler`` and reads the per-operation events XLA:CPU's
thunk executor records. Each operation of the compiled step is classed as *matmul* (a dot or
convolution, alone or inside a fusion) or *other* (elementwise fusions, reductions, copies,
transposes, ...). Reported: the summed operation time per step, each class's share, and the
largest operations. Operations can overlap in time (independent thunks run concurrently), so the
sum can exceed the step's wall time; the shares are what this is for.
"""

from __future__ import annotations

import argparse
import collections
import gzip
import json
import re
import tempfile
from pathlib import Path

import jax
import numpy as np

from timing import median_seconds
from xted.fields import apply_overrides
from xted.data import load
from xted.data.normalizer import Normalizer
from xted.diffusion.config import preset
from xted.diffusion.objective import init_train_state, make_train_step
from xted.diffusion.training import training_windows

_INSTRUCTION = re.compile(r"^\s*(?:ROOT\s+)?%?([\w.\-]+) = .*?\s([a-z][\w\-]*)\((.*)$")
_COMPUTATION = re.compile(r"^(?:ENTRY\s+)?%?([\w.\-]+)\s.*\{\s*$")
_CALLS = re.compile(r"(?:calls|to_apply|body|condition)=%?([\w.\-]+)")
_MATMUL_OPCODES = ("dot", "convolution")


def operation_classes(hlo_text: str) -> dict[str, str]:
    """HLO instruction name -> "matmul" or "other" (a fusion is matmul if it calls a dot)."""
    computations: dict[str, list[tuple[str, str, list[str]]]] = collections.defaultdict(list)
    current = None
    for line in hlo_text.splitlines():
        header = _COMPUTATION.match(line)
        if header and "=" not in line.split("{")[0]:
            current = header.group(1)
            continue
        match = _INSTRUCTION.match(line)
        if match and current is not None:
            name, opcode, rest = match.groups()
            computations[current].append((name, opcode, _CALLS.findall(rest)))

    def has_matmul(computation: str, seen: frozenset = frozenset()) -> bool:
        if computation in seen:
            return False
        return any(op in _MATMUL_OPCODES or any(has_matmul(c, seen | {computation}) for c in calls)
                   for _, op, calls in computations.get(computation, []))

    classes = {}
    for instructions in computations.values():
        for name, opcode, calls in instructions:
            matmul = opcode in _MATMUL_OPCODES or any(has_matmul(c) for c in calls)
            classes[name] = "matmul" if matmul else "other"
    return classes


def trace_operations(trace_dir: Path, module_prefix: str) -> dict[str, float]:
    """Summed microseconds per HLO operation of the traced module(s)."""
    totals: dict[str, float] = collections.defaultdict(float)
    for path in trace_dir.rglob("*.trace.json.gz"):
        with gzip.open(path) as f:
            events = json.load(f)["traceEvents"]
        for event in events:
            args = event.get("args", {})
            if event.get("ph") == "X" and "hlo_op" in args and args.get("hlo_module", "").startswith(module_prefix):
                totals[args["hlo_op"]] += event["dur"]
    return totals


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--target", default="halfcheetah-medium-replay")
    parser.add_argument("--preset", default="cpu")
    parser.add_argument("--steps", type=int, default=20)
    parser.add_argument("--top", type=int, default=12)
    parser.add_argument("--set", dest="overrides", nargs="*", default=[])
    args = parser.parse_args()

    data = load(args.target)
    config = apply_overrides(preset(args.preset, data.observation_dim, data.action_dim), args.overrides)
    sampler, _ = training_windows(data, Normalizer.fit(data), config)
    batch = sampler.batch(np.random.default_rng(0), config.batch_size)
    step = make_train_step(config)
    key = jax.random.key(1)
    holder = {"state": init_train_state(config, key)}
    compiled = step.lower(holder["state"], batch, key).compile()
    classes = operation_classes(compiled.as_text())

    def run():
        holder["state"], metrics = step(holder["state"], batch, key)
        return metrics

    jax.block_until_ready(run())
    wall = median_seconds(run, args.steps)
    with tempfile.TemporaryDirectory() as trace_dir:
        jax.profiler.start_trace(trace_dir)
        for _ in range(args.steps):
            jax.block_until_ready(run())
        jax.profiler.stop_trace()
        totals = trace_operations(Path(trace_dir), "jit_train_step")
    per_step = {name: us / args.steps / 1e3 for name, us in totals.items()}  # ms
    summed = sum(per_step.values())
    by_class = collections.defaultdict(float)
    for name, ms in per_step.items():
        by_class[classes.get(name, "other")] += ms
    report = {
        "preset": args.preset, "overrides": args.overrides, "step_wall_ms": wall * 1e3, "operations_ms": summed,
        "share": {c: ms / summed for c, ms in sorted(by_class.items())},
        "top": [{"op": name, "class": classes.get(name, "other"), "ms": round(ms, 3), "share": round(ms / summed, 4)}
                for name, ms in sorted(per_step.items(), key=lambda kv: -kv[1])[: args.top]],
    }
    print(json.dumps(report, indent=1))


if __name__ == "__main__":
    main()
