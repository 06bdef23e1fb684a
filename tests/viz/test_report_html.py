"""The HTML evaluation report explains itself: definitions, units, every run, videos."""

from __future__ import annotations

import copy
import re
from html.parser import HTMLParser
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from behavior_hmm.errors import ConfigError
from behavior_hmm.evaluate import evaluate_model
from behavior_hmm.models import CBLM, SBLM
from behavior_hmm.runtime import Trace
from behavior_hmm.teach import collect
from behavior_hmm.teach import test_starts as shipped_starts
from behavior_hmm.viz import write_evaluation_report
from behavior_hmm.viz._html import components_text, format_values

DATA_PNG = "data:image/png;base64,"
VOID = {"area", "base", "br", "col", "embed", "hr", "img", "input", "link", "meta", "source",
        "track", "wbr"}  # fmt: skip


@pytest.fixture(scope="module")
def evaluated(turn_model: SBLM) -> tuple[dict[str, Any], dict[str, list[Any]]]:
    """The shared small turn SBLM (tests/conftest.py) on its 15 test starts, runs kept."""
    result = evaluate_model(turn_model, shipped_starts("turn"), sim="kinematic", keep_traces=True)
    traces = result.pop("_traces")
    return result, traces


@pytest.fixture(scope="module")
def page(
    evaluated: tuple[dict[str, Any], dict[str, list[Any]]],
    tmp_path_factory: pytest.TempPathFactory,
) -> str:
    result, traces = evaluated
    path = write_evaluation_report(result, traces, tmp_path_factory.mktemp("r") / "turn.html")
    return path.read_text(encoding="utf-8")


@pytest.fixture(scope="module")
def cblm_evaluated(turn_model: SBLM) -> tuple[dict[str, Any], dict[str, list[Any]]]:
    """A small real CBLM (turn, then approach) on three test starts."""
    approach = SBLM(inputs=("distance", "angle"), epochs=30, random_state=0).fit(
        collect("approach", [{"distance": x} for x in (0.2, 0.4, 0.6, 0.8, 1.0)], sim="kinematic")
    )
    starts = [{"angle": a, "distance": x} for a in (-120.0, -60.0, 60.0, 120.0) for x in (0.3, 0.7)]
    starts += [{"angle": 0.0, "distance": x} for x in (0.3, 0.7)]
    model = CBLM([turn_model, approach], inputs=("distance", "angle")).fit(
        collect("turn-approach", starts, sim="kinematic")
    )
    result = evaluate_model(
        model, shipped_starts("turn-approach")[:3], sim="kinematic", keep_traces=True
    )
    traces = result.pop("_traces")
    return result, traces


class _Checker(HTMLParser):
    """Well-formedness: every element closed in order, ids unique, links and images sound."""

    def __init__(self) -> None:
        super().__init__(convert_charrefs=True)
        self.stack: list[str] = []
        self.errors: list[str] = []
        self.ids: list[str] = []
        self.hrefs: list[str] = []
        self.srcs: list[str] = []
        self.tags: list[str] = []
        self.doctype = False

    def handle_decl(self, decl: str) -> None:
        self.doctype = decl.lower() == "doctype html"

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        self.tags.append(tag)
        values = dict(attrs)
        if "id" in values:
            self.ids.append(str(values["id"]))
        if "href" in values:
            self.hrefs.append(str(values["href"]))
        if "src" in values:
            self.srcs.append(str(values["src"]))
        if tag == "img" and not values.get("alt"):
            self.errors.append(f"an <img> without alt text at {self.getpos()}")
        if tag not in VOID:
            self.stack.append(tag)

    def handle_endtag(self, tag: str) -> None:
        if tag in VOID:
            self.errors.append(f"</{tag}> closes a void element at {self.getpos()}")
        elif not self.stack or self.stack[-1] != tag:
            self.errors.append(f"</{tag}> does not close <{self.stack[-1:]}> at {self.getpos()}")
        else:
            self.stack.pop()


def check_page(text: str) -> _Checker:
    checker = _Checker()
    checker.feed(text)
    checker.close()
    assert checker.doctype, "no <!doctype html>"
    assert not checker.errors, checker.errors
    assert not checker.stack, f"unclosed elements: {checker.stack}"
    assert len(checker.ids) == len(set(checker.ids)), "duplicate ids"
    assert checker.tags[:3] == ["html", "head", "meta"]  # the charset comes first
    for href in checker.hrefs:  # in-page anchors all lead somewhere
        if href.startswith("#"):
            assert href[1:] in checker.ids, f"dangling link {href}"
    # nothing from outside: no script, no remote link, no stylesheet to fetch
    assert "script" not in checker.tags and "link" not in checker.tags
    for url in checker.hrefs + checker.srcs:
        assert not re.match(r"[a-z][a-z0-9+.-]*://", url, re.I), f"external resource {url}"
        assert not url.startswith("//"), f"external resource {url}"
    return checker


def test_format_values_reads_in_units() -> None:
    assert format_values({"angle": 120.0, "distance": 0.5}) == "120°, 0.50 m"
    assert format_values({"angle": -0.0}) == "0°"
    assert format_values({"angle": -37.5}) == "-37.5°"
    assert format_values({"distance": 0.005}) == "0.005 m"
    assert format_values({"linear_velocity": 0.1}) == "linear_velocity 0.10 m/s"
    assert format_values({}) == "–"


def test_components_text_keeps_order_and_shortens() -> None:
    assert components_text(["turn", "approach"]) == "turn → approach"
    long = ["turn", "approach"] * 5
    assert components_text(long) == "turn → approach → turn → approach → … → approach (10 in all)"


def test_page_defines_every_score(page: str) -> None:
    assert "What the numbers mean" in page
    assert "100·(1 − EDM)" in page and "thesis ch. 6" in page
    assert "teacher&#x27;s demonstration from the same start" in page
    for term in ("success %", "all-zero floor %", "motor-max %", "duration ×", "command jump ×"):
        assert f"<dt>{term}</dt>" in page
    assert "<dt>switches</dt><dd>changes of the active motion primitive" in page
    assert "never moves" in page and "motor limit (10 rad/s)" in page


def test_page_is_valid_and_self_contained(page: str) -> None:
    checker = check_page(page)
    assert all(src.startswith(DATA_PNG) for src in checker.srcs)


def test_starts_and_goals_read_in_units(
    page: str, evaluated: tuple[dict[str, Any], dict[str, list[Any]]]
) -> None:
    result, _ = evaluated
    assert "{" not in re.sub(r"<style>.*?</style>", "", page, flags=re.S)  # no dict repr
    for case in result["cases"]:
        angle = round(case["start"]["angle"])
        assert f"<td class='l nw'>{angle}°, 0.50 m</td><td class='l nw'>0°</td>" in page


def test_every_run_is_plotted(
    page: str, evaluated: tuple[dict[str, Any], dict[str, list[Any]]]
) -> None:
    result, _ = evaluated
    assert len(result["cases"]) == 15
    assert page.count(DATA_PNG) == 15
    for k in range(15):
        assert f"<section class='run' id='run-{k}'>" in page
        assert f"<a href='#run-{k}'>{k}</a>" in page
    assert len(page.encode()) < 400_000  # 15 small figures, not megabytes


def test_an_sblm_page_drops_what_it_does_not_have(page: str) -> None:
    # the embedded figures are base64 text, which may spell anything: search without them
    text = re.sub(r"data:[\w/+.-]+;base64,[A-Za-z0-9+/=]+", "", page)
    assert "SBLM on angle (kinematic sim)" in text and "CBLM" not in text
    assert "final angle err" in text  # a turn has an angle goal ...
    assert "final distance err" not in text  # ... and no distance goal
    for absent in ("pushed", "components", "Baselines", "not plotted", "<video"):
        assert absent not in text


def test_baselines_and_pushes_get_their_columns(
    evaluated: tuple[dict[str, Any], dict[str, list[Any]]], tmp_path: Path
) -> None:
    result, traces = copy.deepcopy(evaluated)
    for case in result["cases"]:
        case["pushed"] = True
    result["pushed"] = len(result["cases"])
    summary = {k: v for k, v in result.items() if k not in ("cases", "baselines")}
    result["baselines"] = {"bc": {**summary, "cases": result["cases"]}}
    text = write_evaluation_report(result, traces, tmp_path / "r.html", max_runs=1).read_text()
    check_page(text)
    assert "<td class='l'>bc</td>" in text and "<th>bc %</th>" in text
    assert "<th>pushed</th>" in text and "<dt>pushed</dt>" in text


def test_a_cblm_says_cblm_and_names_its_components(
    cblm_evaluated: tuple[dict[str, Any], dict[str, list[Any]]], tmp_path: Path
) -> None:
    result, traces = cblm_evaluated
    assert result["kind"] == "CBLM"
    text = write_evaluation_report(result, traces, tmp_path / "ta.html").read_text()
    check_page(text)
    assert "CBLM on distance, angle" in text and "model (CBLM)" in text
    assert "SBLM" not in text
    assert "<th class='l'>components</th>" in text
    assert "<dt>switches</dt><dd>changes of the active component" in text
    for case in result["cases"]:
        assert case["components"][0] == "turn"
        assert f"<td class='l'>{components_text(case['components'])}</td>" in text
    # turn & approach has both goals: both final errors are shown
    assert "final angle err" in text and "final distance err" in text
    assert text.count(DATA_PNG) == len(result["cases"])


def test_kind_comes_from_the_result(
    evaluated: tuple[dict[str, Any], dict[str, list[Any]]], tmp_path: Path
) -> None:
    result, traces = copy.deepcopy(evaluated)
    result["kind"] = "CBLM"
    text = write_evaluation_report(result, traces, tmp_path / "r.html", max_runs=1).read_text()
    assert "turn: CBLM on angle" in text and "SBLM" not in text


def test_videos_are_linked_beside_their_runs(
    evaluated: tuple[dict[str, Any], dict[str, list[Any]]], tmp_path: Path
) -> None:
    result, traces = evaluated
    folder = tmp_path / "videos"
    folder.mkdir()
    for name in ("case 00.mp4", "case_03.gif"):
        (folder / name).write_bytes(b"not embedded")
    videos = {0: folder / "case 00.mp4", 3: str(folder / "case_03.gif")}
    path = write_evaluation_report(result, traces, tmp_path / "report.html", 4, videos=videos)
    text = path.read_text()
    check_page(text)
    assert "not embedded" not in text and "bm90IGVtYmVkZGVk" not in text  # (its base64)
    run0 = text[text.index("id='run-0'") : text.index("id='run-1'")]
    assert "<video controls preload='metadata' width='300' src='videos/case%2000.mp4'" in run0
    assert "<a href='videos/case%2000.mp4'>case 00.mp4</a>" in run0
    run3 = text[text.index("id='run-3'") :]
    assert "<a href='videos/case_03.gif'><img alt='video of run 3'" in run3
    assert text.count("<video") == 1 and text.count(DATA_PNG) == 4
    # a report elsewhere links the same files relative to its own folder
    other = write_evaluation_report(result, None, tmp_path / "sub" / "r.html", videos=videos)
    text = other.read_text()
    check_page(text)  # without traces: the videos alone, still beside their cases
    assert "src='../videos/case%2000.mp4'" in text and DATA_PNG not in text
    assert "<a href='#run-3'>3</a>" in text and "<a href='#run-1'>" not in text


def test_bad_videos_are_refused(
    evaluated: tuple[dict[str, Any], dict[str, list[Any]]], tmp_path: Path
) -> None:
    result, traces = evaluated
    with pytest.raises(ConfigError, match="case 15"):
        write_evaluation_report(result, traces, tmp_path / "r.html", videos={15: "a.mp4"})
    with pytest.raises(ConfigError, match="case True"):
        write_evaluation_report(result, traces, tmp_path / "r.html", videos={True: "a.mp4"})
    with pytest.raises(ConfigError, match="neither a video"):
        write_evaluation_report(result, traces, tmp_path / "r.html", videos={0: "a.avi"})
    assert not (tmp_path / "r.html").exists()


def test_tables_only_and_max_runs(
    evaluated: tuple[dict[str, Any], dict[str, list[Any]]], tmp_path: Path
) -> None:
    result, traces = evaluated
    text = write_evaluation_report(result, None, tmp_path / "a.html").read_text()
    check_page(text)
    assert DATA_PNG not in text and "<h2>Runs</h2>" not in text and "<h2>Cases</h2>" in text
    text = write_evaluation_report(result, traces, tmp_path / "b.html", max_runs=2).read_text()
    check_page(text)
    assert text.count(DATA_PNG) == 2 and "Runs 2..14 not plotted" in text


def test_a_refused_run_is_drawn(
    evaluated: tuple[dict[str, Any], dict[str, list[Any]]], tmp_path: Path
) -> None:
    """A run refused before any motion (an unreachable goal): one step, no readings."""
    result, traces = copy.deepcopy(evaluated)
    trace = Trace(goal={"angle": 0.0}, start={"angle": 30.0}, channels=["angle", "distance"])
    trace.t.append(0.0)
    trace.commands.append(np.zeros(2))
    trace.component.append("")
    trace.final_observation = np.array([30.0, 0.5])
    trace.reason = "unreachable: no"
    traces["model"][0] = (trace, traces["model"][0][1])
    result["cases"][0].update(goal_reached=False, reason=trace.reason)
    text = write_evaluation_report(result, traces, tmp_path / "r.html", max_runs=1).read_text()
    check_page(text)
    assert text.count(DATA_PNG) == 1
    assert "<span class='fail'>no</span> (unreachable: no)" in text
