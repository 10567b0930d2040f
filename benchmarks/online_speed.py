"""The online RL loop against its update alone, side by side in one process (SAC and TD3).

    python benchmarks/online_speed.py [--algos sac td3] [--steps 10000] [--repeats 5]

For each algorithm: (a) the update alone, as one jitted per-update call on a fixed batch (the old
loop's best case) and as ``train_block``'s ``fori_loop`` of ``block`` updates on batches drawn from
the device buffer; (b) ``xted online train``'s whole loop (env steps, acting, buffer writes,
updates) over ``--steps`` learning steps on halfcheetah, read from its own evaluation log, the
evaluation excluded and the compile done beforehand. Prints JSON lines.
"""

from __future__ import annotations

import argparse
import json
import statistics
import tempfile
import time

import jax
import numpy as np

from xted.envs import parse_domain
from xted.rl.online import ONLINE_ALGORITHMS, OnlineRunConfig, empty_buffer, read_evals, train_block, train_online

OBS_DIM, ACTION_DIM = 17, 6


def device_buffer(size: int, rng: np.random.Generator) -> dict:
    host = empty_buffer(size, OBS_DIM, ACTION_DIM)
    for key in ("observations", "actions", "rewards", "next_observations"):
        host[key][:] = rng.normal(size=host[key].shape)
    return {k: jax.device_put(v) for k, v in host.items()}


def update_only(config: OnlineRunConfig, buffer_size: int, repeats: int) -> dict:
    algorithm, agent = ONLINE_ALGORITHMS[config.algo], config.agent
    rng = np.random.default_rng(0)
    state = algorithm.init(jax.random.PRNGKey(0), OBS_DIM, ACTION_DIM, agent, 0)
    buffer = device_buffer(buffer_size, rng)
    rows = {k: np.asarray(buffer[k][:config.block]) for k in buffer}
    key = jax.random.PRNGKey(1)
    per_block = []
    for i in range(repeats + 1):  # the first call compiles
        started = time.perf_counter()
        state, buffer = train_block(state, buffer, rows, 0, buffer_size - config.block, config.block, i * config.block,
                                    key, update=algorithm.update, config=agent)
        jax.block_until_ready(state)
        per_block.append(time.perf_counter() - started)
    if repeats == 0:
        return {}
    idx = rng.integers(0, 10_000, agent.batch_size)
    batch = {k: np.asarray(buffer[k][idx], np.float32) for k in ("observations", "actions", "rewards",
                                                                  "next_observations", "terminals")}
    update = jax.jit(algorithm.update, static_argnames="config")
    per_call = []
    for _ in range(repeats * config.block + 1):
        started = time.perf_counter()
        state, _ = update(state, batch, config=agent)
        jax.block_until_ready(state)
        per_call.append(time.perf_counter() - started)
    return {"scan_updates_per_second": config.block / statistics.median(per_block[1:]),
            "call_updates_per_second": 1 / statistics.median(per_call[1:])}


def whole_loop(config: OnlineRunConfig) -> float:
    """Learning-phase env steps per second of the full loop (each step is also one update)."""
    # Compile train_block for this run's shapes first, so the timed loop holds no compile.
    update_only(config, config.total_steps + config.block, repeats=0)
    with tempfile.TemporaryDirectory() as folder:
        train_online(parse_domain("halfcheetah"), folder, config, progress=False)
        first, last = read_evals(folder)
    learning_steps = last["step"] - first["step"]
    return learning_steps / (last["wall_seconds"] - first["wall_seconds"] - last["eval_seconds"])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--algos", nargs="+", default=["sac", "td3"])
    parser.add_argument("--steps", type=int, default=10_000, help="learning steps of the whole loop")
    parser.add_argument("--start-steps", type=int, default=5_000)
    parser.add_argument("--repeats", type=int, default=20, help="blocks timed for the update alone")
    args = parser.parse_args()
    for algo in args.algos:
        config = OnlineRunConfig(algo=algo, total_steps=args.start_steps + args.steps, start_steps=args.start_steps,
                                 checkpoint_every=args.start_steps, eval_episodes=1)
        update = update_only(config, config.total_steps + config.block, args.repeats)
        loop = whole_loop(config)
        print(json.dumps({"algo": algo, "block": config.block, **update, "loop_steps_per_second": loop,
                          "loop_over_scan": loop / update["scan_updates_per_second"],
                          "loop_over_call": loop / update["call_updates_per_second"]}), flush=True)


if __name__ == "__main__":
    main()
