"""Reinforcement learning on a learned reward: does RL on it recover the expert's driving?

A small policy-gradient agent (plain torch REINFORCE) learns to pick one of the planner's sampled policies
per 0.2 s cycle in ``irlsim/Planning-v0``, rewarded by a learned reward (any of the seven models, or
``expert-theta``). Then it, the expert, the learned reward's own planner (argmax of its value, what
``irlsim drive`` drives) and a uniformly random agent drive the same evaluation seeds, and the closed-loop
scorecard (irlsim.drive.scorecard) of each is reported.

The agent scores every policy with a small MLP over (log(1 + features) [15], the features standardised
over the cycle's policies [15], labels [3]) and samples from the softmax over the cycle's N policies (a
permutation-equivariant policy: no Python loop over policies). REINFORCE with the discounted return
(gamma 0.5: the reward is mostly the current choice's), returns standardised per episode, Adam; training
seeds are disjoint from the evaluation seeds. Run (about the minutes given plus the evaluation)::

    python examples/rl_on_learned_reward.py --runs runs/default --reward PACNN+S \\
        --config configs/collect/default.toml --minutes 5 --out runs/default/rl
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path
from typing import Any

import numpy as np
import torch
from torch import nn

TRAIN_SEED_BASE = 5_000_000  # training episodes use seeds TRAIN_SEED_BASE + seed * 10_000 + i


class PolicyScorer(nn.Module):
    """logits [N] = MLP(log1p(f) ++ standardised f ++ labels) [N, 33], shared over the policies."""

    def __init__(self, hidden: int = 32):
        super().__init__()
        self.net = nn.Sequential(nn.Linear(33, hidden), nn.Tanh(), nn.Linear(hidden, 1))

    def forward(self, features: torch.Tensor, labels: torch.Tensor) -> torch.Tensor:
        f = features.clamp_min(0.0)
        z = (f - f.mean(dim=-2, keepdim=True)) / (f.std(dim=-2, keepdim=True) + 1e-6)
        x = torch.cat([torch.log1p(f), z, labels.float()], dim=-1)
        return self.net(x).squeeze(-1)


def _tensors(obs: dict[str, np.ndarray]) -> tuple[torch.Tensor, torch.Tensor]:
    return torch.as_tensor(obs["features"]), torch.as_tensor(obs["labels"])


def train(
    env: Any, agent: PolicyScorer, seconds: float, seed: int, gamma: float, lr: float
) -> dict[str, Any]:
    opt = torch.optim.Adam(agent.parameters(), lr=lr)
    history, t0, i = [], time.perf_counter(), 0
    while time.perf_counter() - t0 < seconds:
        obs, _ = env.reset(seed=TRAIN_SEED_BASE + seed * 10_000 + i)
        logps, rewards, done = [], [], False
        while not done:
            dist = torch.distributions.Categorical(logits=agent(*_tensors(obs)))
            a = dist.sample()
            logps.append(dist.log_prob(a))
            obs, r, term, trunc, info = env.step(int(a))
            rewards.append(r)
            done = term or trunc
        ret = np.zeros(len(rewards))
        acc = 0.0
        for k in range(len(rewards) - 1, -1, -1):  # discounted return: one pass per episode
            acc = rewards[k] + gamma * acc
            ret[k] = acc
        adv = torch.as_tensor((ret - ret.mean()) / (ret.std() + 1e-8), dtype=torch.float32)
        loss = -(torch.stack(logps) * adv).mean()
        opt.zero_grad()
        loss.backward()
        opt.step()
        history.append(
            {
                "episode": i,
                "cycles": len(rewards),
                "mean_reward": round(float(np.mean(rewards)), 4),
                "end": info.get("end_reason"),
            }
        )
        print(
            f"train episode {i}: {len(rewards)} cycles, mean reward {np.mean(rewards):.3f}, "
            f"end {info.get('end_reason')}, {time.perf_counter() - t0:.0f} s",
            flush=True,
        )
        i += 1
    return {"episodes": i, "seconds": round(time.perf_counter() - t0, 1), "history": history}


def evaluate(env: Any, agents: dict[str, Any], seeds: list[int]) -> dict[str, list[dict[str, Any]]]:
    """Every agent drives every seed; the expert first, as the progress reference."""
    out: dict[str, list[dict[str, Any]]] = {name: [] for name in agents}
    reference: dict[int, Any] = {}
    for name, act in agents.items():
        for seed in seeds:
            obs, _ = env.reset(seed=seed)
            rng = np.random.default_rng(seed)
            rewards, done = [], False
            while not done:
                obs, r, term, trunc, _ = env.step(act(env, obs, rng))
                rewards.append(r)
                done = term or trunc
            if name == "expert":
                reference[seed] = env.unwrapped.progress_curve()
            rec = env.unwrapped.episode_scorecard(reference.get(seed))
            rec.update(
                agent=name, seed=seed, cycles=len(rewards), mean_reward=round(float(np.mean(rewards)), 4)
            )
            out[name].append(rec)
            print(
                f"eval {name} seed {seed}: score {rec['score/score']:.1f}, end {rec['end_reason']}, "
                f"{rec['sim/mean_speed_kmh']:.1f} km/h, mean reward {rec['mean_reward']:.3f}",
                flush=True,
            )
    return out


def table(results: dict[str, list[dict[str, Any]]]) -> str:
    keys = (
        "score/no_collision",
        "score/no_exit",
        "score/stop_lines",
        "score/ttc",
        "score/progress",
        "score/comfort",
        "score/mission",
    )
    rows = [
        "| agent | episodes | score (mean ± std) | mean reward | collisions | exits | km/h | "
        + " | ".join(k.split("/")[1] for k in keys)
        + " |",
        "|" + "---|" * (7 + len(keys)),
    ]
    for name, recs in results.items():
        sc = np.array([r["score/score"] for r in recs])

        def mean(k: str, recs: list[dict[str, Any]] = recs) -> str:
            v = [r[k] for r in recs if r.get(k) is not None]
            return f"{np.mean(v):.2f}" if v else "-"

        rows.append(
            f"| {name} | {len(recs)} | {sc.mean():.1f} ± {sc.std():.1f} | {mean('mean_reward')} "
            f"| {sum(r['sim/collisions'] for r in recs)} | {sum(r['sim/exits'] for r in recs)} "
            f"| {mean('sim/mean_speed_kmh')} | " + " | ".join(mean(k) for k in keys) + " |"
        )
    return "\n".join(rows) + "\n"


def main() -> int:
    import gymnasium as gym

    import irlsim.envs  # noqa: F401  (registers irlsim/Planning-v0)
    from irlsim.utils import atomic_path, atomic_write_text, seed_everything, write_json

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument(
        "--reward", default="expert-theta", help="expert-theta, a model name (with --runs) or a checkpoint"
    )
    p.add_argument("--runs", type=Path, default=None, help="runs folder of the trained models")
    p.add_argument("--config", type=Path, default=None, help="the collect TOML the model was trained with")
    p.add_argument("--minutes", type=float, default=3.0, help="training wall time [min]")
    p.add_argument("--max-cycles", type=int, default=150, help="cycles per episode (150 = 30 s)")
    p.add_argument("--eval-episodes", type=int, default=3, help="evaluation episodes per agent")
    p.add_argument("--eval-seed", type=int, default=900, help="evaluation seeds S..S+E-1")
    p.add_argument("--seed", type=int, default=0, help="seed of the agent and its training episodes")
    p.add_argument("--gamma", type=float, default=0.5)
    p.add_argument("--lr", type=float, default=3e-3)
    p.add_argument("--out", type=Path, default=Path("runs/rl"))
    args = p.parse_args()

    seed_everything(args.seed)
    torch.set_num_threads(1)
    env = gym.make(
        "irlsim/Planning-v0",
        reward=args.reward,
        runs=args.runs,
        config=args.config,
        max_cycles=args.max_cycles,
    )
    agent = PolicyScorer()
    log = train(env, agent, 60.0 * args.minutes, args.seed, args.gamma, args.lr)

    @torch.no_grad()
    def greedy(env: Any, obs: dict[str, np.ndarray], rng: Any) -> int:
        return int(agent(*_tensors(obs)).argmax())

    agents = {
        "expert": lambda env, obs, rng: env.unwrapped.expert_action(),
        f"argmax V ({env.unwrapped.reward_name})": lambda env, obs, rng: int(np.argmax(env.unwrapped.values)),
        "REINFORCE (greedy)": greedy,
        "random": lambda env, obs, rng: int(rng.integers(0, env.action_space.n)),
    }
    seeds = list(range(args.eval_seed, args.eval_seed + args.eval_episodes))
    results = evaluate(env, agents, seeds)
    env.close()
    md = (
        f"# RL on the learned reward {env.unwrapped.reward_name}\n\nREINFORCE, {log['episodes']} training "
        f"episodes of <= {args.max_cycles} cycles in {log['seconds']} s; evaluation seeds "
        f"{seeds[0]}..{seeds[-1]}, "
        f"<= {args.max_cycles} cycles each.\n\n{table(results)}"
    )
    write_json(
        args.out / "rl.json",
        {"args": {k: str(v) for k, v in vars(args).items()}, "train": log, "eval": results},
    )
    atomic_write_text(args.out / "rl.md", md)
    with atomic_path(args.out / "agent.pt") as tmp:
        torch.save(agent.state_dict(), tmp)
    print("\n" + md)
    print(f"wrote {args.out}/rl.json, {args.out}/rl.md, {args.out}/agent.pt")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
