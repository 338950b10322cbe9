"""Rollout videos: one run's frames as an MP4 (PyAV, no system FFmpeg), and runs side by side."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from lerobot_gcs_push.files import atomic_path
from lerobot_gcs_push.scene import Scene


def write_video(path: Path, frames: list[np.ndarray], fps: float) -> None:
    import av

    with atomic_path(path) as tmp, av.open(str(tmp), mode="w", format="mp4") as container:
        stream = container.add_stream("mpeg4", rate=int(round(fps)))
        stream.height, stream.width = frames[0].shape[:2]
        stream.pix_fmt = "yuv420p"
        stream.bit_rate = 2_000_000
        for img in frames:
            for packet in stream.encode(av.VideoFrame.from_ndarray(np.ascontiguousarray(img), format="rgb24")):
                container.mux(packet)
        for packet in stream.encode():
            container.mux(packet)


def side_by_side(videos: list[Path], labels: list[str], out: Path, gif: Path | None = None, gif_every: int = 3) -> Path:
    """One video of several rollouts from the same initial condition, side by side and in step (a run
    that ends first holds its last frame), each under its label; optionally a GIF for the README."""
    import av
    import cv2

    clips = []
    for path in videos:
        with av.open(str(path)) as container:
            clips.append([f.to_ndarray(format="rgb24") for f in container.decode(video=0)])
    if not clips or not all(clips):
        raise ValueError(f"no frames in {videos}")
    n = max(len(c) for c in clips)
    frames = []
    for k in range(n):
        tiles = []
        for clip, label in zip(clips, labels):
            img = np.ascontiguousarray(clip[min(k, len(clip) - 1)])
            done = k >= len(clip) - 1
            cv2.putText(
                img,
                label + (" (done)" if done else ""),
                (8, 22),
                cv2.FONT_HERSHEY_SIMPLEX,
                0.55,
                (0, 0, 0),
                1,
                cv2.LINE_AA,
            )
            tiles.append(img)
        frames.append(np.hstack(tiles))
    write_video(out, frames, Scene.fps)
    if gif is not None:
        from PIL import Image

        small = [Image.fromarray(f).resize((f.shape[1] // 2, f.shape[0] // 2)) for f in frames[::gif_every]]
        small[0].save(
            gif,
            save_all=True,
            append_images=small[1:],
            duration=int(1000 * gif_every / Scene.fps),
            loop=0,
            optimize=True,
        )
    return out
