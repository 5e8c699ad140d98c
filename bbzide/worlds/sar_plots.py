"""Plots of `bbzide experiment sar` (PNG, matplotlib with the Agg back end: no display needed).

Design: one function per figure of thesis §5.4, fed with the run dictionaries of
`sar_experiment.run_one` (also what `runs/*.json` hold), so plots can be redrawn from a finished
folder. Box plots follow Figs. 5.6-5.11: one figure per arena, drone counts on the x axis, the
random walk and the belief search side by side (the paper's green/orange for the find time,
red/blue for the relay formation). The bandwidth plot follows Fig. 5.12: the bytes each drone
sent per simulated second over one run (the first belief run of the smallest configuration),
with the random walk of the same pair as a dashed per-drone mean.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

COLOURS_FIND = {"random": "tab:green", "belief": "tab:orange"}
COLOURS_RELAY = {"random": "tab:red", "belief": "tab:blue"}


def _pyplot() -> Any:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def box_plot(results: Sequence[dict[str, Any]], arena: float, key: str, ylabel: str,
             colours: dict[str, str], path: Path) -> Path:
    plt = _pyplot()
    runs = [r for r in results if r["arena"] == arena and r[key] >= 0]
    drones = sorted({r["drones"] for r in results if r["arena"] == arena})
    searches = [s for s in ("random", "belief") if any(r["search"] == s for r in runs)]
    fig, ax = plt.subplots(figsize=(6, 4))
    width = 0.8 / max(len(searches), 1)
    for k, search in enumerate(searches):
        data = [[r[key] for r in runs if r["drones"] == d and r["search"] == search]
                for d in drones]
        positions = [i + (k - (len(searches) - 1) / 2) * width for i in range(len(drones))]
        parts = ax.boxplot([d if d else [float("nan")] for d in data], positions=positions,
                           widths=width * 0.9, patch_artist=True,
                           medianprops={"color": "black"})
        for box in parts["boxes"]:
            box.set_facecolor(colours[search])
        ax.plot([], [], color=colours[search], linewidth=8, label=search)
    ax.set_xticks(range(len(drones)), [str(d) for d in drones])
    ax.set_xlabel("drones")
    ax.set_ylabel(ylabel)
    ax.set_title(f"{arena:g} m x {arena:g} m arena")
    if searches:
        ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


def bandwidth_plot(result: dict[str, Any], path: Path,
                   baseline: dict[str, Any] | None = None) -> Path:
    """Bytes each drone sent per simulated second; `baseline` (the random walk of the same
    pair) is drawn as its per-drone mean, dashed, to show what the belief gossip adds."""
    plt = _pyplot()
    samples = result["bandwidth"]   # per second: bytes sent by each drone
    fig, ax = plt.subplots(figsize=(7, 4))
    if samples:
        for drone in range(len(samples[0])):
            ax.plot(range(1, len(samples) + 1), [s[drone] for s in samples], linewidth=0.8)
    if baseline and baseline.get("bandwidth"):
        means = [sum(s) / len(s) for s in baseline["bandwidth"]]
        ax.plot(range(1, len(means) + 1), means, "k--", linewidth=2,
                label=f"{baseline['search']} search, same seed: mean per drone")
        ax.legend()
    ax.set_xlabel("simulated time (s)")
    ax.set_ylabel("bytes sent per second, per drone")
    ax.set_title(f"{result['drones']} drones, {result['arena']:g} m arena, "
                 f"{result['search']} search (run {result['run_id']})")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


def write_all(out: Path, results: Sequence[dict[str, Any]]) -> list[Path]:
    written = []
    for arena in sorted({r["arena"] for r in results}):
        written.append(box_plot(results, arena, "found_all_step",
                                "timesteps to find all targets", COLOURS_FIND,
                                out / f"find_time_arena{arena:g}.png"))
        written.append(box_plot(results, arena, "relay_formation_steps",
                                "relay formation (root's auctioneer timesteps)", COLOURS_RELAY,
                                out / f"relay_time_arena{arena:g}.png"))
    candidates = sorted((r for r in results if r.get("bandwidth")),
                        key=lambda r: (r["search"] != "belief", r["arena"], r["drones"],
                                       r["trial"]))
    if candidates:
        shown = candidates[0]
        partner = next((r for r in results if r["search"] != shown["search"]
                        and (r["arena"], r["drones"], r["trial"])
                        == (shown["arena"], shown["drones"], shown["trial"])), None)
        written.append(bandwidth_plot(shown, out / "bandwidth.png", partner))
    return written
