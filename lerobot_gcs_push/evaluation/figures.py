"""The paper's figures from evaluation records: Fig. 4 (training images averaged), Fig. 6 (success map),
Fig. 7 (GCS and policy trajectories overlaid; a rotating slider's outline along them)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from lerobot_gcs_push.evaluation.success import success_measures
from lerobot_gcs_push.registration import SCENES
from lerobot_gcs_push.scene import Scene

OUTLINES_ALONG_PATH = 4  # a rotating slider's outlines drawn along a run, its end included


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def make_figures(cfg, out: Path, records: list[dict], ics: list[dict]) -> list[str]:
    made = [
        fig6_success_map(cfg, out, records, ics),
        fig7_trajectories(cfg, out, records, ics),
        fig_regret(cfg, out, records),
    ]
    if cfg.dataset:
        made.append(fig4_dataset_initial_images(cfg.dataset, out / "fig4_training_initial_images.png"))
    return [str(p) for p in made if p is not None]


def _variants(records):
    seen = []
    for r in records:
        if r["label"] not in seen:
            seen.append(r["label"])
    return seen


def fig6_success_map(cfg, out: Path, records: list[dict], ics: list[dict]) -> Path | None:
    labels = _variants(records)
    if not labels:
        return None
    plt = _plt()
    scene = SCENES[cfg.starts.env_id]
    measure = success_measures(cfg)
    fig, axes = plt.subplots(1, len(labels), figsize=(4 * len(labels), 4), squeeze=False)
    lim = scene.box_limit
    for ax, label in zip(axes[0], labels):
        rates = []
        for i in range(len(ics)):
            rs = [r[measure.loose_key] for r in records if r["label"] == label and r["initial_condition_index"] == i]
            rates.append(np.mean(rs) if rs else np.nan)
        box = np.array([ic["box"] for ic in ics])
        sc = ax.scatter(box[:, 0], box[:, 1], c=rates, cmap="viridis", vmin=0, vmax=1, s=70, edgecolors="k")
        for i, (x, y) in enumerate(box):
            ax.annotate(str(i), (x, y), textcoords="offset points", xytext=(5, 5), fontsize=7)
        ax.plot(*scene.goal, marker="*", color="tab:green", ms=14)
        ax.set_xlim(-lim - 0.5, lim + 0.5)
        ax.set_ylim(-lim - 0.5, lim + 0.5)
        ax.set_aspect("equal")
        ax.set_title(label, fontsize=9)
    fig.colorbar(sc, ax=axes[0].tolist(), label=measure.loose)
    fig.suptitle(f"Initial box positions coloured by {measure.loose} (paper Fig. 6)")
    path = out / "fig6_success_map.png"
    fig.savefig(path, dpi=110, bbox_inches="tight")
    plt.close(fig)
    return path


def fig7_trajectories(cfg, out: Path, records: list[dict], ics: list[dict], max_ics: int = 6) -> Path | None:
    """Per initial condition: the GCS open-loop finger path (thick) and each other policy's (thin), brighter
    with time, over the scene at its initial state; a rotating slider's outline at a few poses along each
    path, in the path's colour."""
    labels = _variants(records)
    if not labels:
        return None
    plt = _plt()
    from matplotlib.collections import LineCollection

    scene = SCENES[cfg.starts.env_id]
    n = min(max_ics, len(ics))
    fig, axes = plt.subplots(1, n, figsize=(3.2 * n, 3.4), squeeze=False)
    cmaps = ["Greys", "Blues", "Oranges", "Purples", "Reds", "Greens"]
    lim = scene.view_half_width
    for i, ax in zip(range(n), axes[0]):
        draw_start_and_goal(ax, scene, ics[i])
        for j, label in enumerate(labels):
            rec = next(
                (r for r in records if r["label"] == label and r["initial_condition_index"] == i and r["run"] == 0),
                None,
            )
            # Trajectories stay with the outputs (not in results/): a figure redrawn elsewhere skips them.
            if rec is None or not (out / rec["trajectory"]).is_file():
                continue
            traj = np.load(out / rec["trajectory"])
            finger = traj["finger"]
            if len(finger) < 2:
                continue
            if scene.kind.drawn_as_outline:
                draw_slider_path(ax, scene, traj["slider_pose"], plt.get_cmap(cmaps[j % len(cmaps)])(0.8))
            segs = np.stack([finger[:-1], finger[1:]], axis=1)
            thick = label == "gcs-open-loop"
            lc = LineCollection(
                segs, cmap=cmaps[j % len(cmaps)], linewidths=4.0 if thick else 1.3, alpha=0.8, label=label
            )
            lc.set_array(np.linspace(0.35, 1.0, len(segs)))
            lc.set_clim(0, 1.2)
            ax.add_collection(lc)
            ax.plot(*finger[0], "ko", ms=3)
        ax.set_xlim(-lim, lim)
        ax.set_ylim(-lim, lim)
        ax.set_aspect("equal")
        ax.set_xticks([])
        ax.set_yticks([])
        ax.set_title(f"IC {i}", fontsize=9)
    handles = [
        plt.Line2D(
            [], [], color=plt.get_cmap(cmaps[j % len(cmaps)])(0.8), lw=4 if name == "gcs-open-loop" else 1.5, label=name
        )
        for j, name in enumerate(labels)
    ]
    fig.legend(handles=handles, loc="lower center", ncol=len(labels), fontsize=8)
    fig.suptitle("Finger trajectories, brighter with time (paper Fig. 7)")
    path = out / "fig7_trajectories.png"
    fig.savefig(path, dpi=110, bbox_inches="tight")
    plt.close(fig)
    return path


def fig_regret(cfg, out: Path, records: list[dict]) -> Path | None:
    """Cumulative regret along each run, per policy: flat lines are optimal play; a step up is a mistake,
    and where the first large one happens tells which phase (approach or push) the policy gets wrong."""
    labels = [
        label for label in _variants(records) if any("regret_chunks" in r for r in records if r["label"] == label)
    ]
    if not labels:
        return None
    plt = _plt()
    fig, axes = plt.subplots(1, len(labels), figsize=(4 * len(labels), 3.4), squeeze=False, sharey=True)
    fps = Scene().fps
    for ax, label in zip(axes[0], labels):
        for r in (r for r in records if r["label"] == label and r.get("regret_chunks")):
            ch = np.array(r["regret_chunks"], float)
            last = ch[-1, 0] - ch[-2, 0] if len(ch) > 1 else 1  # the chunk length the run was scored with
            t = np.r_[ch[:, 0], ch[-1, 0] + last] / fps
            cum = np.r_[0.0, np.nancumsum(ch[:, 1])]
            ax.plot(t, cum, color="tab:green" if r["success"] else "tab:red", lw=0.8, alpha=0.6)
        ax.axhline(0, color="k", lw=0.5)
        ax.set_title(label, fontsize=9)
        ax.set_xlabel("simulated time (s)")
    axes[0][0].set_ylabel("cumulative regret (m)")
    fig.suptitle("regret against the GCS cost-to-go (green: success, red: failure)", fontsize=9)
    fig.tight_layout()
    path = out / "fig_regret.png"
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def draw_start_and_goal(ax, scene: Scene, ic: dict) -> None:
    """The slider at the initial condition (red) and the goal (green): squares for the box that cannot
    turn, outlines at their poses for a rotating slider."""
    if not scene.kind.drawn_as_outline:
        ax.add_patch(_rect(ic["box"], scene.box_half, "tab:red", 0.35))
        ax.add_patch(_rect(scene.goal, scene.box_half, "tab:green", 0.35))
        return
    from matplotlib.patches import Polygon

    start = scene.shape.world_outline((*ic["box"], ic.get("heading", 0.0)))
    ax.add_patch(Polygon(start, closed=True, color="tab:red", alpha=0.35, gid="start"))
    ax.add_patch(
        Polygon(scene.shape.world_outline(scene.goal_pose), closed=True, color="tab:green", alpha=0.35, gid="goal")
    )


def draw_slider_path(ax, scene: Scene, poses, color) -> None:
    """A rotating slider's outline at `OUTLINES_ALONG_PATH` poses spread over the run (x, y, heading per
    row), the last one its final pose: where it went and how it turned."""
    from matplotlib.patches import Polygon

    poses = np.asarray(poses, float)
    picks = np.unique(np.linspace(0, len(poses) - 1, OUTLINES_ALONG_PATH + 1).round().astype(int))[1:]
    for k in picks:  # the start is drawn filled with the scene
        outline = scene.shape.world_outline(poses[k])
        ax.add_patch(Polygon(outline, closed=True, fill=False, edgecolor=color, lw=0.9, gid="along_path"))


def _rect(center, half, color, alpha):
    from matplotlib.patches import Rectangle

    return Rectangle((center[0] - half, center[1] - half), 2 * half, 2 * half, color=color, alpha=alpha)


def fig4_dataset_initial_images(dataset: str, path: Path) -> Path:
    """The first image of every training episode, averaged, beside the initial box positions (Fig. 4)."""
    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    p = Path(dataset)
    ds = (
        LeRobotDataset(p.name, root=p, video_backend="pyav")
        if p.is_dir()
        else LeRobotDataset(dataset, video_backend="pyav")
    )
    starts = np.asarray(ds.meta.episodes["dataset_from_index"])
    imgs, boxes = [], []
    for s in starts:
        item = ds[int(s)]
        imgs.append(item["observation.image"].numpy().transpose(1, 2, 0))
        boxes.append(item["observation.environment_state"].numpy())
    mean = np.mean(imgs, axis=0)
    boxes = np.array(boxes)
    plt = _plt()
    fig, (a, b) = plt.subplots(1, 2, figsize=(8, 4))
    a.imshow(np.clip(mean, 0, 1))
    a.set_title(f"{len(imgs)} initial images averaged")
    a.axis("off")
    lim = Scene().box_limit
    b.scatter(boxes[:, 0], boxes[:, 1], s=12)
    b.set_xlim(-lim - 0.5, lim + 0.5)
    b.set_ylim(-lim - 0.5, lim + 0.5)
    b.set_aspect("equal")
    b.set_title("initial box positions")
    fig.suptitle("Training dataset coverage (paper Fig. 4)")
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110, bbox_inches="tight")
    plt.close(fig)
    return path
