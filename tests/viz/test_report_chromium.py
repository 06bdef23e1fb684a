"""The HTML evaluation report in a real browser (headless Chromium, its own CLI).

Checks that the page logs nothing to the console, that every image (the embedded run
figures and a linked GIF) and every video (a linked MP4) loads, and that a screenshot
renders. Skipped where no ``chromium`` (or ``chromium-browser``) is on the PATH
(Debian/Ubuntu: ``apt-get install chromium``).
"""

from __future__ import annotations

import html
import json
import re
import shutil
import subprocess
from pathlib import Path
from typing import Any

import pytest

from behavior_hmm.evaluate import evaluate_model
from behavior_hmm.models import SBLM
from behavior_hmm.teach import test_starts as shipped_starts
from behavior_hmm.viz import write_evaluation_report

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
pytestmark = pytest.mark.skipif(
    CHROMIUM is None,
    reason="needs headless Chromium: no `chromium` or `chromium-browser` on the PATH "
    "(Debian/Ubuntu: apt-get install chromium)",
)

#: Injected into a copy of the report (the report itself has no script): once the page
#: has loaded, wait for every video's metadata (or its error), then write what loaded
#: into <pre id="bhmm-check"> for --dump-dom to show. A video counts as loaded when its
#: file was found and parsed as a video of known size (readyState >= 1, videoWidth > 0):
#: under --virtual-time-budget the page's timers run ahead of real time, so waiting for
#: a decoded frame (readyState >= 2) would depend on the machine's load.
PROBE = """<script>
window.addEventListener("load", function () {
  var videos = Array.prototype.slice.call(document.querySelectorAll("video"));
  var tries = 0;
  function report() {
    var pending = videos.filter(function (v) { return v.readyState < 1 && !v.error; });
    if (pending.length && tries++ < 100) { setTimeout(report, 100); return; }
    var out = {
      images: Array.prototype.map.call(document.images, function (i) {
        return {src: i.getAttribute("src").slice(0, 40), ok: i.complete && i.naturalWidth > 0};
      }),
      videos: videos.map(function (v) {
        return {src: v.getAttribute("src"), state: v.readyState,
                error: v.error ? v.error.code : 0, width: v.videoWidth,
                ok: !v.error && v.readyState >= 1 && v.videoWidth > 0};
      })
    };
    var pre = document.createElement("pre");
    pre.id = "bhmm-check";
    pre.textContent = JSON.stringify(out);
    document.body.appendChild(pre);
  }
  report();
});
</script>"""


def chromium(tmp: Path, url: str, *args: str) -> subprocess.CompletedProcess[str]:
    """Run headless Chromium on ``url`` with its own throw-away profile."""
    assert CHROMIUM is not None
    profile = tmp / "profile"
    command = [
        CHROMIUM,
        "--headless=new",
        "--no-sandbox",  # as root, and in containers
        "--disable-gpu",
        "--no-first-run",
        "--disable-extensions",
        "--mute-audio",
        f"--user-data-dir={profile}",
        *args,
        url,
    ]
    done = subprocess.run(command, capture_output=True, text=True, timeout=180, check=False)
    assert done.returncode == 0, done.stderr[-2000:]
    return done


def console_messages(stderr: str) -> list[str]:
    """What the page wrote to the console (``--enable-logging=stderr`` logs it as CONSOLE)."""
    return [line for line in stderr.splitlines() if ":CONSOLE" in line]


def probe(tmp: Path, report: Path) -> dict[str, Any]:
    """Load a copy of ``report`` with :data:`PROBE` beside it; what loaded."""
    text = report.read_text(encoding="utf-8")
    assert "<script" not in text
    copy = report.with_name(f"probe-{report.name}")
    copy.write_text(text.replace("</body>", PROBE + "</body>"), encoding="utf-8")
    done = chromium(
        tmp,
        copy.as_uri(),
        "--virtual-time-budget=15000",
        "--enable-logging=stderr",
        "--v=0",
        "--dump-dom",
    )
    assert not console_messages(done.stderr), console_messages(done.stderr)
    found = re.search(r'<pre id="bhmm-check">(.*?)</pre>', done.stdout, re.S)
    assert found, f"the probe did not report:\n{done.stdout[-1500:]}"
    out: dict[str, Any] = json.loads(html.unescape(found.group(1)))
    return out


@pytest.fixture(scope="module")
def report(turn_model: SBLM, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A 3-run report with an MP4 (where imageio-ffmpeg is installed) and a GIF linked."""
    from behavior_hmm.sim import make_env
    from behavior_hmm.viz import render_trace

    folder = tmp_path_factory.mktemp("report")
    result = evaluate_model(
        turn_model, shipped_starts("turn")[:3], sim="kinematic", keep_traces=True
    )
    traces = result.pop("_traces")
    env = make_env("kinematic")
    videos: dict[int, Path] = {}
    fast: dict[str, Any] = {"robot": env, "fps": 10.0, "speed": 4.0}
    render_trace(traces["model"][1][0], folder / "videos" / "case_01.gif", **fast)
    videos[1] = folder / "videos" / "case_01.gif"
    try:
        import imageio_ffmpeg  # noqa: F401
    except ImportError:
        pass
    else:
        render_trace(traces["model"][0][0], folder / "videos" / "case 00.mp4", **fast)
        videos[0] = folder / "videos" / "case 00.mp4"
    return write_evaluation_report(result, traces, folder / "turn.html", videos=videos)


def test_report_logs_nothing_to_the_console(report: Path, tmp_path: Path) -> None:
    done = chromium(
        tmp_path,
        report.as_uri(),
        "--virtual-time-budget=5000",
        "--enable-logging=stderr",
        "--v=0",
        "--dump-dom",
    )
    assert not console_messages(done.stderr), console_messages(done.stderr)
    assert "<h1>behavior-hmm evaluation: turn: SBLM on angle (kinematic sim)</h1>" in done.stdout


def test_every_image_and_video_loads(report: Path, tmp_path: Path) -> None:
    out = probe(tmp_path, report)
    images = out["images"]
    assert len(images) == 4  # three embedded run figures and the GIF
    assert sum(i["src"].startswith("data:image/png;base64,") for i in images) == 3
    assert all(i["ok"] for i in images), images
    if (report.parent / "videos" / "case 00.mp4").exists():
        assert len(out["videos"]) == 1
        assert all(v["ok"] for v in out["videos"]), out["videos"]


def test_the_probe_sees_a_missing_file(report: Path, tmp_path: Path) -> None:
    """The check is not vacuous: a linked video that is not there is caught."""
    from behavior_hmm.errors import ConfigError

    folder = report.parent
    for name in ("gone.gif", "gone.mp4"):
        assert not (folder / name).exists()
    result = {
        "behavior": "turn",
        "kind": "SBLM",
        "inputs": ["angle"],
        "sim": "kinematic",
        "command_scale": 1.0,
        "motor_max": 10.0,
        "cases": [
            {
                "start": {"angle": a, "distance": 0.5},
                "goal": {"angle": 0.0},
                "success_rate": 90.0,
                "zero_floor": 40.0,
                "goal_reached": True,
                "duration_ratio": 1.0,
                "switches": 2,
            }
            for a in (10.0, 20.0)
        ],
        "n": 2,
        "success_rate_mean": 90.0,
        "zero_floor_mean": 40.0,
        "goal_reached": 2,
        "success_rate_motor_max_mean": 99.0,
        "zero_floor_motor_max_mean": 94.0,
        "duration_ratio_mean": 1.0,
    }
    broken = write_evaluation_report(
        result,
        None,
        folder / "broken.html",
        videos={0: folder / "gone.gif", 1: folder / "gone.mp4"},
    )
    out = probe(tmp_path, broken)
    assert [i["ok"] for i in out["images"]] == [False]
    assert [v["ok"] for v in out["videos"]] == [False]
    with pytest.raises(ConfigError):  # and an unknown kind of file is refused up front
        write_evaluation_report(result, None, folder / "x.html", videos={0: "gone.txt"})


def test_screenshot_renders(report: Path, tmp_path: Path) -> None:
    from PIL import Image

    shot = tmp_path / "report.png"
    chromium(
        tmp_path,
        report.as_uri(),
        "--virtual-time-budget=5000",
        "--hide-scrollbars",
        "--window-size=1200,2000",
        f"--screenshot={shot}",
    )
    with Image.open(shot) as image:
        assert image.size == (1200, 2000)
        grey = image.convert("L")
        lo, hi = grey.getextrema()
        assert hi - lo > 128  # text and plots, not a blank page
        # the plots: many distinct shades (a blank or error page has few)
        assert len(grey.getcolors(maxcolors=256 * 256) or []) > 32
