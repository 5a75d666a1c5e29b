"""Seeing runs: animations, the timeline and fairness pictures, and comparisons of run directories."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from PIL import Image

from aac_sumo.cli.app import main

SWARM = ["run", "swarm_rescue", "--set", "scenario.duration=1.0", "--set", "controller.horizon=5"]


@pytest.fixture(scope="module")
def swarm_run(tmp_path_factory):
    """A one-second swarm rescue written with ``run --animate``."""
    out = tmp_path_factory.mktemp("views") / "swarm"
    assert main([*SWARM, "--out", str(out), "--animate", "--ellipses"]) == 0
    return out


def recorded_times(run_dir) -> int:
    return pd.read_csv(run_dir / "trajectories.csv")["t"].nunique()


def test_run_animate_writes_one_gif_frame_per_recorded_period(swarm_run):
    gif = Image.open(swarm_run / "animation.gif")
    assert gif.n_frames == recorded_times(swarm_run) == 11  # t = 0.0 .. 1.0 s
    sizes = set()
    for k in range(gif.n_frames):
        gif.seek(k)
        sizes.add(gif.size)
    assert sizes == {(1000, gif.size[1])} and gif.size[1] % 2 == 0 and gif.size[1] > 200


def test_the_gif_writer_keeps_each_frame_in_the_palette_form_a_gif_stores(swarm_run, tmp_path):
    """Frames are held one byte a pixel (GIF's 256-colour palette) from the moment they are
    grabbed, not three: the same pictures in a third of the memory."""
    import matplotlib.pyplot as plt

    from aac_sumo.views.animate import PaletteGifWriter

    fig, ax = plt.subplots(figsize=(2, 1), dpi=50)
    writer = PaletteGifWriter(fps=5)
    with writer.saving(fig, tmp_path / "two.gif", dpi=50):
        for colour in ("tab:red", "tab:blue"):
            ax.set_facecolor(colour)
            writer.grab_frame()
            assert writer._frames[-1].mode == "P"
    plt.close(fig)
    with Image.open(tmp_path / "two.gif") as gif:
        assert gif.n_frames == 2
        first = gif.convert("RGB").getpixel((50, 25))
        gif.seek(1)
        assert gif.convert("RGB").getpixel((50, 25)) != first


def test_animate_writes_an_mp4_with_every_kth_frame(swarm_run, capsys):
    import imageio_ffmpeg

    assert main(["animate", str(swarm_run), "--format", "mp4", "--every", "2", "--fps", "5"]) == 0
    assert "6 frames" in capsys.readouterr().out
    frames, seconds = imageio_ffmpeg.count_frames_and_secs(str(swarm_run / "animation.mp4"))
    assert frames == 6 and seconds == pytest.approx(6 / 5, abs=0.01)


def test_animate_still_writes_the_frame_nearest_to_a_time(swarm_run, capsys):
    assert main(["animate", str(swarm_run), "--still", "0.52"]) == 0
    assert "t = 0.5 s" in capsys.readouterr().out
    with Image.open(swarm_run / "frame_0.52.png") as frame:
        assert frame.size == Image.open(swarm_run / "animation.gif").size


def test_every_run_writes_its_timeline_and_fairness_pictures(swarm_run):
    for name in ("timeline.png", "fairness.png"):
        with Image.open(swarm_run / name) as picture:
            assert picture.format == "PNG" and min(picture.size) > 300, name


def test_the_fairness_picture_shows_only_the_robots_that_were_recorded(tmp_path):
    """A run stopped before every car departed (the highway: cars enter over time) has delays
    for all its robots but steps for those on the road; the picture is drawn for the latter (an
    interrupted 100-car run lost its pictures to a shape mismatch). Over three periods robot a
    held authority twice and b once: a got 2 / 1.5 = 4/3 of its fair share, b 1 / 1.5 = 2/3.
    Robot a arrived 1.5 s late, b did not arrive (a grey bar at 0), c never departed (no bar)."""
    from types import SimpleNamespace

    import matplotlib.colors as mcolors
    import matplotlib.pyplot as plt
    import numpy as np

    from aac_sumo.views.timeline import fairness_figure, plot_fairness

    steps = pd.DataFrame({"t": [0.0, 0.0, 0.1, 0.1, 0.2, 0.2], "robot": ["a", "b"] * 3,
                          "authority": [True, False, False, True, True, False], "arrived": [False] * 6})
    result = SimpleNamespace(steps=steps, metrics={"authority_jain": 0.9, "delay_jain": None, "delay_max_s": 1.5,
                                                   "scenario": "highway_work_zone", "coordinator": "aac", "horizon": 10, "seed": 0},
                             scenario=SimpleNamespace(kind="lane_change"))
    delays = pd.Series([1.5, np.nan, np.nan], index=["a", "b", "c"])
    fig = fairness_figure(result, delays)
    try:
        fig.canvas.draw()
        top, bottom = fig.axes
        assert [label.get_text() for label in bottom.get_xticklabels()] == ["a", "b"]
        assert [p.get_height() for p in top.patches] == pytest.approx([4 / 3, 2 / 3])
        assert [p.get_height() for p in bottom.patches] == pytest.approx([1.5, 0.0])
        assert [mcolors.to_hex(p.get_facecolor()) for p in bottom.patches] == [mcolors.to_hex("tab:orange"), mcolors.to_hex("0.8")]
        assert [line.get_ydata()[0] for line in top.get_lines()] == [1.0]  # the fair share
        assert top.get_title() == "authority_jain 0.90"
        assert bottom.get_title() == "delay_jain —, delay_max_s 1.50; grey: did not arrive"
        assert "c" not in {t.get_text() for ax in fig.axes for t in ax.get_xticklabels()}
    finally:
        plt.close(fig)
    plot_fairness(result, tmp_path / "fairness.png", delays)
    with Image.open(tmp_path / "fairness.png") as picture:
        assert picture.format == "PNG" and picture.size == (600, 650)


@pytest.mark.parametrize("argv, expected", [
    (["animate", "no/such/dir"], "no/such/dir: expected a run directory"),
    (["animate", ".", "--format", "avi"], "--format: invalid choice: 'avi'"),
    (["animate", ".", "--fps", "-1"], "--fps: expected a number > 0"),
])
def test_animate_bad_input_is_one_line(capsys, argv, expected):
    assert main(argv) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and expected in err[0], err


def test_compare_puts_runs_side_by_side(swarm_run, tmp_path, capsys):
    lfc = tmp_path / "lfc"
    assert main([*SWARM, "--set", "controller.coordinator=lfc", "--out", str(lfc)]) == 0
    out = tmp_path / "cmp"
    assert main(["compare", str(swarm_run), str(lfc), "--out", str(out)]) == 0
    table = pd.read_csv(out / "compare.csv")
    assert list(table["run"]) == ["swarm", "lfc"] and list(table["coordinator"]) == ["aac", "lfc"]
    assert {"min_clearance_m", "authority_jain", "task_duration_s"} <= set(table.columns)
    md = (out / "compare.md").read_text()
    assert "| metric | swarm | lfc |" in md and "| coordinator | aac | lfc |" in md
    assert Image.open(out / "compare.png").format == "PNG"


@pytest.mark.parametrize("argv, expected", [
    (["compare", "a", "--out", "x"], "compare: expected two or more RUN_DIRs, got 1"),
    (["compare", "no/run", "other", "--out", "x"], "no/run: expected a run directory"),
    (["compare", "a", "b"], "the following arguments are required: --out"),
])
def test_compare_bad_input_is_one_line(capsys, argv, expected):
    assert main(argv) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and expected in err[0], err


@pytest.mark.parametrize("length, equal", [(420.0, False), (12.0, True)])
def test_compare_draws_paths_to_scale_unless_they_are_a_long_road(tmp_path, monkeypatch, length, equal):
    """The paths panel keeps equal axes for paths about as long as wide (a 12 m x 9.6 m area),
    and lets a 420 m road three lanes wide fill the panel, saying its axes are not to scale (with
    equal axes it was a flat line)."""
    from types import SimpleNamespace

    from aac_sumo.views import compare

    t = np.arange(3) * 0.1
    steps = pd.DataFrame(dict(t=np.repeat(t, 2), robot=["a", "b"] * 3, v=1.0, clearance_m=1.0, arrived=False))
    traj = pd.DataFrame(dict(name=["a"] * 3 + ["b"] * 3, kind="controlled", x=[0.0, length / 2, length] * 2,
                             y=[-8.0, -8.0, -8.0, -1.6, -1.6, 1.6]))
    figures = []
    monkeypatch.setattr(compare.plt, "close", figures.append)
    run = SimpleNamespace(steps=steps, trajectories=traj, metrics={"horizon": 10, "n_robots": 2}, scenario=SimpleNamespace(kind="lane_change"))
    compare.plot({"one": run}, tmp_path / "c.png")
    paths = figures[0].axes[-1]
    assert (paths.get_aspect() == 1.0) == equal
    assert ("not to scale" in paths.get_title()) == (not equal)
    assert ("not to scale" in paths.get_ylabel()) == (not equal)  # the lateral axis says how much it is stretched
    legend = [text.get_text() for text in figures[0].axes[0].get_legend().get_texts()]
    assert legend == ["one (horizon N=10, 2 cars)"]  # a bare "N=10" read as ten cars
    arrived = figures[0].axes[2]
    assert arrived.get_ylabel() == "cars arrived"
    assert all(float(tick).is_integer() for tick in arrived.get_yticks())  # whole cars (it showed 12.5 of 15)
    assert arrived.get_ylim()[0] <= 0.0 and arrived.get_ylim()[1] >= 2.0  # from none to the whole fleet


def test_compare_counts_a_robot_arrived_from_its_first_arrived_row_on_also_after_it_left():
    from aac_sumo.views.compare import arrivals_over_time

    steps = pd.DataFrame(dict(t=[0.0, 0.0, 0.1, 0.1, 0.2], robot=["a", "b", "a", "b", "b"], arrived=[False, False, True, False, True]))
    assert arrivals_over_time(steps).tolist() == [0, 1, 2]  # a has left at 0.2 and still counts


def test_titles_say_the_horizon_and_how_many_cars():
    from aac_sumo.views.titles import horizon_and_fleet

    assert horizon_and_fleet({"horizon": 10, "n_robots": 15}, "lane_change") == "horizon N=10, 15 cars"
    assert horizon_and_fleet({"horizon": 5, "n_robots": 1}, "swarm_rescue") == "horizon N=5, 1 robot"


@pytest.mark.parametrize("road, zoomed", [(2750.0, True), (420.0, False)])
def test_the_road_picture_zooms_to_the_cars_on_a_long_road(road, zoomed):
    """On a 2.75 km road the cars' 60 m of motion was a blob: the panel zooms to their extent
    (plus a margin) and says so; a 420 m road the cars drive along stays whole."""
    import matplotlib.pyplot as plt

    from aac_sumo.views.lane_change import ZOOM_MARGIN, zoom_to_cars

    fig, ax = plt.subplots()
    ax.plot([0.0, road], [-8.0, 8.0])
    ax.autoscale()
    span = 60.0 if zoomed else road
    cars = pd.DataFrame(dict(x=[100.0, 100.0 + span], y=[-4.8, -1.6]))
    assert zoom_to_cars(ax, cars) == zoomed
    if zoomed:
        assert ax.get_xlim() == pytest.approx((100.0 - ZOOM_MARGIN, 160.0 + ZOOM_MARGIN))
    plt.close(fig)
