"""The live page in headless Chromium (Playwright): a running run, `forcelearn view` of it."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from importlib import resources
from pathlib import Path

import numpy as np
import pytest
from matplotlib.image import imread

from forcelearn.tools.live import screenshot
from forcelearn.tools.live.browser import find_chromium, headless_page, wait_rendered

CLI = (
    # Ctrl-C must reach the child even when this suite was started as a background job,
    # whose children inherit SIGINT ignored
    "import signal, sys; signal.signal(signal.SIGINT, signal.default_int_handler); "
    "from forcelearn.tools.cli import main; sys.exit(main(sys.argv[1:]))"
)
pytestmark = [
    pytest.mark.slow,
    pytest.mark.skipif(
        find_chromium() is None,
        reason="no chromium on PATH (.ci/run installs Debian's chromium; or set "
        "FORCELEARN_CHROMIUM to one); Playwright never downloads its own",
    ),
]


def page_url(child: subprocess.Popen[bytes], prefix: str) -> str:
    """The URL a forcelearn child prints on stderr."""
    assert child.stderr is not None
    for raw in child.stderr:
        line = raw.decode()
        if line.startswith(prefix):
            return line[len(prefix) :].split()[0]
    child.wait()
    raise AssertionError(f"no page URL; exit {child.returncode}")


def assert_not_blank(path: Path) -> None:
    """A screenshot with plots has many colours and contrast, not one flat colour."""
    pixels = imread(path)[..., :3]
    rgb = (pixels * 255).astype(np.uint32).reshape(-1, 3)
    # one 24-bit number a colour: np.unique(axis=0) on the rows takes seconds a screenshot
    colours = np.unique((rgb[:, 0] << 16) | (rgb[:, 1] << 8) | rgb[:, 2])
    assert len(colours) > 50, f"{path} looks blank ({len(colours)} colours)"
    assert pixels.std() > 0.05


@pytest.mark.timeout(600)  # a whole run, a browser and a view: minutes on a loaded host
def test_live_page_of_a_running_run_and_view_of_the_finished_run(
    tmp_path: Path, configured_map_toml: str
) -> None:
    """Plots drawn, the status panel's trial advances, screenshots not blank.

    The run has its whole output map configured, so it does not probe (the probed
    run's live data are checked against its files in test_live.py); the browser is
    started before the run, so the run's trials are all the page has to catch up on.
    """
    out = tmp_path / "run"
    config = tmp_path / "cell.toml"
    config.write_text(configured_map_toml)
    trials = os.environ.get("FORCELEARN_LIVE_TRIALS", "24")
    with headless_page() as page:
        run = subprocess.Popen(
            [
                *(sys.executable, "-c", CLI, "run", "--trials", trials, "--out", str(out)),
                *("--config", str(config), "--no-progress", "--live", "--live-port", "0"),
            ],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.PIPE,
        )
        try:
            url = page_url(run, "live page: ")
            page.goto(url)
            first = wait_rendered(page, canvases=4)
            later = wait_rendered(page, canvases=4, after_trial=first["trial"])
            assert later["trial"] > first["trial"]
            assert later["drawn"] == 4
            live_png = tmp_path / "live_run.png"
            page.screenshot(path=live_png)
            assert run.wait(timeout=600) == 0
        finally:
            if run.poll() is None:
                run.kill()
                run.wait()
    assert_not_blank(live_png)

    view = subprocess.Popen(
        [sys.executable, "-c", CLI, "view", str(out), "--port", "0"],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
    )
    try:
        url = page_url(view, "page of the run: ")
        with headless_page() as page:
            page.goto(url)
            seen = wait_rendered(page, canvases=4, after_trial=int(trials) - 2)
            assert seen["state"] == "finished"
            assert seen["trials_done"] == int(trials)
            view_png = tmp_path / "live_view.png"
            page.screenshot(path=view_png)
        assert_not_blank(view_png)
    finally:
        view.send_signal(signal.SIGINT)
        assert view.wait(timeout=60) == 0

    # The README's figure program, on the same run directory: its page during a trial
    at = int(trials) - 5
    png = tmp_path / "live_at.png"
    seen = screenshot.screenshot(screenshot.load_model(out, at), png, 1400, 720)
    assert seen["status"] == f"{at} of {trials} ({at - 1} done)"
    assert seen["state"] == "running"
    assert seen["drawn"] == 4
    assert_not_blank(png)


def test_a_plot_legend_goes_to_the_corner_its_data_leave_free() -> None:
    """Data in the top right corner (the legend's usual place) push the legend to the top left."""
    plot_js = (resources.files("forcelearn.tools.live") / "static" / "plot.js").read_text()
    with headless_page(600, 400) as page:
        page.set_content('<canvas id="c" style="width:400px;height:260px"></canvas>')
        page.add_script_tag(content=plot_js)
        seen = page.evaluate(
            """() => {
              const canvas = document.getElementById("c");
              const x = [], y = [];
              for (let i = 0; i < 60; i++) { x.push(7 + (i % 10) / 3.3); y.push(7 + i / 20); }
              Plot.draw(canvas, {
                xlim: [0, 10], ylim: [0, 10],
                series: [{ x, y, width: 0, marker: "dot", color: "#c62828", label: "data" }],
              });
              const context = canvas.getContext("2d");
              const pixel = (px, py) => Array.from(context.getImageData(px, py, 1, 1).data);
              const area = { left: 56, top: 10, pw: 334, ph: 216 };
              return {
                topLeft: pixel(area.left + 8, area.top + 6),
                empty: Plot.legendCorner(80, 30, area, []),
                upperHalf: Plot.legendCorner(
                  80, 30, area, [[100, 20], [350, 20], [60, 30], [380, 30]]),
              };
            }"""
        )
    red, green, blue, alpha = seen["topLeft"]
    assert alpha > 150 and min(red, green, blue) > 200, f"no legend at the top left: {seen}"
    assert seen["empty"] == [56 + 334 - 6 - 80, 14]  # top right when nothing is hidden
    assert seen["upperHalf"] == [56 + 334 - 6 - 80, 10 + 216 - 6 - 30]  # then bottom right
