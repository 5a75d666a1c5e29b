"""Animation of a recorded run: every agent's footprint over time, the authority robot and the
robots in a safety stop highlighted, optionally each robot's safety ellipse, a time stamp and
the current authority on every frame. GIF through Pillow, MP4 through the ffmpeg binary that the
imageio-ffmpeg package ships."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.animation import FFMpegWriter, PillowWriter  # noqa: E402
from PIL import Image  # noqa: E402
from matplotlib.collections import PolyCollection  # noqa: E402
from matplotlib.patches import Patch  # noqa: E402

from aac_sumo.barriers import FcbfParams, cbf_axes, fcbf_axes  # noqa: E402
from aac_sumo.config import ScenarioError  # noqa: E402
from aac_sumo.views.titles import horizon_and_fleet  # noqa: E402

#: Face colours by agent kind (trajectories.csv ``kind``); controlled robots get their own colour.
KIND_COLOURS = {"static": "0.55", "scripted": "0.35", "cone": "tab:orange", "pedestrian": "tab:red"}
KIND_LABELS = {"static": "debris", "scripted": "scripted vehicle", "cone": "cone", "pedestrian": "pedestrian"}
AUTHORITY, SAFETY_STOP = "gold", "red"
#: A world wider than this many times its height is shown through a window following the robots.
FOLLOW_ASPECT = 3.0


def corners(x, y, heading, length, width) -> np.ndarray:
    """Footprint corners (n, 4, 2) of rectangles with centres ``x, y`` [m], ``heading`` [rad]."""
    c, s = np.cos(heading), np.sin(heading)
    u = 0.5 * np.asarray(length)[:, None] * np.column_stack([c, s])
    v = 0.5 * np.asarray(width)[:, None] * np.column_stack([-s, c])
    centre = np.column_stack([x, y])
    return np.stack([centre + u + v, centre - u + v, centre - u - v, centre + u - v], axis=1)


def ellipse_outlines(centre: np.ndarray, a, b, phi, points: int = 32) -> np.ndarray:
    """Outlines (n, points, 2) of ellipses with semi-axes ``a, b`` [m] turned by ``phi`` [rad]."""
    theta = np.linspace(0.0, 2.0 * np.pi, points, endpoint=False)
    ex, ey = np.asarray(a)[:, None] * np.cos(theta), np.asarray(b)[:, None] * np.sin(theta)
    c, s = np.cos(phi)[:, None], np.sin(phi)[:, None]
    return np.stack([centre[:, :1] + c * ex - s * ey, centre[:, 1:] + s * ex + c * ey], axis=2)


def safety_axes(scenario, rows):
    """Each controlled robot's safety ellipse as the others see it: ``controller.barrier``'s
    semi-axes [m] and orientation [rad] from its footprint and velocity (trajectories rows)."""
    heading, v = rows["heading"].to_numpy(), rows["v"].to_numpy()
    length, width = rows["length"].to_numpy(), rows["width"].to_numpy()
    if scenario["controller.barrier"] == "cbf":
        return cbf_axes(length, width, heading)
    c = scenario.data["controller"]
    velocity = v[:, None] * np.column_stack([np.cos(heading), np.sin(heading)])
    return fcbf_axes(length, width, velocity, heading, FcbfParams(c["mu1"], c["mu2"], c["sigmoid_k"], c["v0"]))


def frame_notes(steps) -> dict[float, tuple[list[str], set[str], set[str]]]:
    """Per period time [s]: the authority robots (with their reason), the robots in a safety
    stop and the robots whose solve failed."""
    notes = {}
    for t, rows in steps.groupby(steps["t"].round(6), sort=True):
        held = rows[rows["authority"].astype(bool)]
        authority = [f"{r} ({why})" if isinstance(why, str) and why else r for r, why in zip(held["robot"], held["reason"])]
        stopped = set(rows.loc[rows["mode"] == "safety_stop", "robot"])
        failed = set(rows.loc[rows["status"].isin(("infeasible", "failed")), "robot"])
        notes[t] = (authority, stopped, failed)
    return notes


def animate(result, path: Path, fps: float | None = None, every: int = 1, ellipses: bool = False, dpi: int = 100,
            progress: bool = False) -> int:
    """Write the animation of ``result`` (a :class:`~aac_sumo.runs.recording.RunResult`) to ``path``
    (``.gif`` or ``.mp4``): one frame per ``every`` recorded periods, ``fps`` frames per second
    (default: real time), with a progress bar when ``progress``. Returns the number of frames."""
    from tqdm import tqdm

    fig, draw, times = scene(result, ellipses, dpi)
    times = times[::every]
    fps = fps or 1.0 / (result.scenario["scenario.dt"] * every)
    writer = _writer(Path(path).suffix.lstrip("."), fps)
    with writer.saving(fig, str(path), dpi), tqdm(times, desc=f"animate {Path(path).name}", unit="frame", disable=not progress,
                                                  dynamic_ncols=True) as frames:
        for t in frames:  # one render a frame, the writer's (matplotlib's FuncAnimation renders each twice)
            draw(t)
            writer.grab_frame()
    plt.close(fig)
    return len(times)


def still(result, path: Path, t: float, ellipses: bool = False, dpi: int = 100) -> float:
    """Write the frame of the recorded time nearest to ``t`` [s] as a picture (``.png``); returns
    that time [s]."""
    fig, draw, times = scene(result, ellipses, dpi)
    nearest = float(times[np.argmin(np.abs(times - t))])
    draw(nearest)
    fig.savefig(path, dpi=dpi)
    plt.close(fig)
    return nearest


def scene(result, ellipses: bool, dpi: int):
    """The figure of a run, ``draw(t)`` that shows it at recorded time ``t`` [s], and the
    recorded times (sorted)."""
    scenario, traj, m = result.scenario, result.trajectories, result.metrics
    times = np.sort(traj["t"].round(6).unique())
    frames = {t: rows for t, rows in traj.groupby(traj["t"].round(6), sort=True)}
    notes = frame_notes(result.steps)
    robots = list(dict.fromkeys(traj.loc[traj["kind"] == "controlled", "name"]))
    palette = plt.get_cmap("tab10" if len(robots) <= 10 else "tab20")
    colour = {name: palette(i % palette.N) for i, name in enumerate(robots)}

    fig, ax, window = _figure(traj, dpi)
    if scenario.kind == "lane_change":
        from aac_sumo.views.lane_change import draw_road

        try:
            draw_road(ax, scenario)
        except ScenarioError as exc:  # the run directory moved away from its network file
            print(f"note: road not drawn: {exc}")
    for name in robots:  # each robot's whole path, faint, for context
        path_rows = traj[traj["name"] == name]
        ax.plot(path_rows["x"], path_rows["y"], color=colour[name], lw=0.8, alpha=0.3)
    bodies = ax.add_collection(PolyCollection([], linewidths=1.0, zorder=3))
    regions = ax.add_collection(PolyCollection([], facecolors="none", edgecolors="0.3", linestyles="--", linewidths=0.7, zorder=2))
    caption = ax.set_title("", fontsize="medium", loc="left")
    kinds = [k for k in KIND_COLOURS if k in set(traj["kind"])]
    ax.legend(handles=[Patch(facecolor=AUTHORITY, edgecolor="k", label="authority"),
                       Patch(facecolor="mistyrose", edgecolor=SAFETY_STOP, label="safety stop")]
              + [Patch(color=KIND_COLOURS[k], label=KIND_LABELS[k]) for k in kinds],
              fontsize="small", loc="upper right", ncol=2 + len(kinds) // 2)
    title = f"{m['scenario']}: {str(m['coordinator']).upper()}, {m['barrier']}, {horizon_and_fleet(m, scenario.kind)}, seed {m['seed']}"

    def draw(t):
        rows = frames[t]
        authority, stopped, failed = notes.get(t, ([], set(), set()))
        names = rows["name"].tolist()
        held = {a.split(" ")[0] for a in authority}
        bodies.set_verts(corners(rows["x"], rows["y"], rows["heading"], rows["length"], rows["width"]))
        bodies.set_facecolors([AUTHORITY if n in held else "mistyrose" if n in stopped else colour.get(n) or KIND_COLOURS.get(k, "0.5")
                               for n, k in zip(names, rows["kind"])])
        bodies.set_edgecolors([SAFETY_STOP if n in stopped else "k" if n in held else "0.2" if k == "controlled"
                               else KIND_COLOURS.get(k, "0.5") for n, k in zip(names, rows["kind"])])
        bodies.set_linewidths([2.0 if n in held or n in stopped else 0.6 if k == "controlled" else 1.5
                               for n, k in zip(names, rows["kind"])])
        if ellipses:
            mine = rows[rows["kind"] == "controlled"]
            a, b, phi = safety_axes(scenario, mine)
            regions.set_verts(ellipse_outlines(mine[["x", "y"]].to_numpy(), a, b, phi))
        if window is not None:
            window(ax, rows)
        extra = (f"   safety stop: {', '.join(sorted(stopped))}" if stopped else "") + \
                (f"   failed solve: {', '.join(sorted(failed))}" if failed else "")
        caption.set_text(f"{title}\nt = {t:6.2f} s   authority: {', '.join(authority) or '-'}{extra}")
        return bodies, regions, caption

    return fig, draw, times


def _figure(traj, dpi: int):
    """The figure and axes (even pixel sizes, as video encoders want), and for a long world
    (a road) a function that moves the view with the controlled robots each frame."""
    pad = float(traj["length"].max())
    x0, x1 = traj["x"].min() - pad, traj["x"].max() + pad
    y0, y1 = traj["y"].min() - pad, traj["y"].max() + pad
    window = None
    if x1 - x0 > FOLLOW_ASPECT * (y1 - y0):
        ours = traj[traj["kind"] == "controlled"]
        spread = ours.groupby(ours["t"].round(6))["x"].agg(lambda x: x.max() - x.min()).max()
        width = max(spread + 4.0 * pad, FOLLOW_ASPECT * (y1 - y0))

        centre = 0.5 * (x0 + x1)

        def follow_robots(ax, rows):
            mine = rows.loc[rows["kind"] == "controlled", "x"]
            mid = 0.5 * (mine.min() + mine.max()) if len(mine) else centre
            ax.set_xlim(mid - 0.5 * width, mid + 0.5 * width)

        window, x0, x1 = follow_robots, 0.0, width
    inches_w = 10.0 if window is None else 12.0
    inches_h = float(np.clip(inches_w * (y1 - y0) / (x1 - x0), 2.5, 8.0)) + 1.0
    size = [2 * round(v * dpi / 2) / dpi for v in (inches_w, inches_h)]
    fig, ax = plt.subplots(figsize=size, dpi=dpi)
    ax.set_xlim(x0, x1)
    ax.set_ylim(y0, y1)
    ax.set_aspect("equal", adjustable="box")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    fig.subplots_adjust(left=0.07, right=0.98, bottom=0.1, top=0.86)
    return fig, ax, window


class PaletteGifWriter(PillowWriter):
    """matplotlib's GIF writer, keeping each frame as it comes in GIF's own 256-colour palette
    form (one byte a pixel) instead of RGB (three): the GIF holds no more colours than that
    anyway, and a 337-frame lane change then needs a third of the memory."""

    def grab_frame(self, **savefig_kwargs):
        super().grab_frame(**savefig_kwargs)
        frame = self._frames[-1]
        if frame.mode == "RGB":
            self._frames[-1] = frame.quantize(colors=256, method=Image.Quantize.FASTOCTREE, dither=Image.Dither.NONE)

    def finish(self):
        """Write the GIF, handing each frame over as Pillow takes its own copy of it (it keeps
        every frame until the file is written), so that the frames are not held twice."""
        frames = self._frames

        def rest():
            for k in range(1, len(frames)):
                frame, frames[k] = frames[k], None
                yield frame

        frames[0].save(self.outfile, save_all=True, append_images=rest(), duration=int(1000 / self.fps), loop=0)


def _writer(fmt: str, fps: float):
    if fmt not in ("gif", "mp4"):
        raise ValueError(f"animation format {fmt!r}: expected gif or mp4")
    if fmt == "mp4":
        import imageio_ffmpeg

        matplotlib.rcParams["animation.ffmpeg_path"] = imageio_ffmpeg.get_ffmpeg_exe()
        return FFMpegWriter(fps=fps, codec="libx264", extra_args=["-pix_fmt", "yuv420p"])
    return PaletteGifWriter(fps=fps)
