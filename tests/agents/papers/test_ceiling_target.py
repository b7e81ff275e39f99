"""The ceiling-target reproduction (quick mode) and the corridor section of the demo."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from agents.cli import main
from agents.papers.ceiling_target import QUICK_FIT_IMAGES, paper, static
from agents.papers.ceiling_target.demo import corridor_section
from envs.sensors.ceiling_camera import CeilingCamera
from tests.console import assert_aligned, printed_tables


@pytest.fixture(scope="module")
def quick(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, str]:
    out = tmp_path_factory.mktemp("ceiling")
    import io
    from contextlib import redirect_stdout

    printed = io.StringIO()
    with redirect_stdout(printed):
        assert main(["reproduce", "ceiling-target", "--quick", "--out", str(out)]) == 0
    return out, printed.getvalue()


def test_quick_run_writes_report_results_and_figures(quick: tuple[Path, str]) -> None:
    out, printed = quick
    report = (out / "report.md").read_text()
    for section in (
        "Tables 2-4",
        "Tables 5-6",
        "among people",
        "Consistency",
        "illumination",
        "without stopping",
        "how far apart",
    ):
        assert section in report, section
    assert (out / "tables_2_4.png").stat().st_size > 0 and (out / "run.json").is_file()
    tables = printed_tables(printed)
    assert tables and all(assert_aligned(t) is None for t in tables)


def test_the_illumination_study_runs_under_each_modelled_light(quick: tuple[Path, str]) -> None:
    # beside the gain sweep, each light (a camera override) with the shipped and the refitted thresholds
    out = quick[0]
    results = json.loads((out / "results.json").read_text())
    report = (out / "report.md").read_text()
    assert list(results["illumination_light"]) == [light.name for light in static.LIGHTS]
    for light in static.LIGHTS:
        study = results["illumination_light"][light.name]
        assert light.name in report
        assert study["camera"] == json.loads(json.dumps(dict(light.camera)))
        assert study["fit_images"]["train"] == QUICK_FIT_IMAGES
        assert set(study["fitted"]) >= {"red", "green"}
        for which in ("shipped thresholds", "fitted under this light"):
            rows = study["rows"][which]
            assert [(r["space"], r["gain"]) for r in rows] == [(s, g) for s in ("hsv", "rgb") for g in static.LIGHT_GAINS]
            assert all(0 <= r["fix_rate"] <= 1 for r in rows)
    # the colourless study is still there, as it was
    assert list(results["illumination"]) == ["learned over gains 0.6-1.4 (shipped)", "learned at one light (gains 0.95-1.05)"]


def test_static_tables_against_the_paper(quick: tuple[Path, str]) -> None:
    results = json.loads((quick[0] / "results.json").read_text())
    calibrated = results["claim"]["calibrated"]
    assert calibrated["rotation_holds"] and calibrated["position_holds"]
    # one calibration constant on pixels 1.2 times taller than wide: Y_R reads about 1.2 times long
    # and the rotation errors follow sin(2 theta), as the paper's Tables 2 and 4
    aspect = results["static"]["one constant, aspect 1.2"]
    y15 = next(r for r in aspect["y"] if r["y_cm"] == 15)
    assert y15["mean"] == pytest.approx(15 * 1.2, abs=0.6)
    rot30 = next(r for r in aspect["rotation"] if r["rotation_deg"] == 30)
    rot120 = next(r for r in aspect["rotation"] if r["rotation_deg"] == 120)
    assert rot30["mean"] > 32 and rot120["mean"] < 118
    assert len(aspect["rotation"]) == len(paper.TABLE2_ROTATION_DEG)


def test_drives_without_and_with_correction(quick: tuple[Path, str]) -> None:
    summary = json.loads((quick[0] / "results.json").read_text())["drive_summary"]
    last = str(paper.DRIVE_TARGETS_M[-1])
    assert summary["table5"][last]["y_mean"] == pytest.approx(paper.TABLE5_AT_TARGET3_CM[1], abs=4.0)
    for y in paper.DRIVE_TARGETS_M:
        corrected = summary["corrected crowd 0"][str(y)]
        assert corrected["n"] >= 1 and abs(corrected["y_mean"]) < 3 and abs(corrected["x_mean"]) < 3


def test_dead_reckoning_alone_is_overconfident_and_the_fixes_keep_it_honest(quick: tuple[Path, str]) -> None:
    # the drift model is a random walk and knows nothing of the odometry's 2.2 % scale error
    drives = json.loads((quick[0] / "results.json").read_text())["drives"]
    uncorrected = [d["inside_95"] for d in drives["table5"]]
    corrected = [d["inside_95"] for d in drives["corrected crowd 0"]]
    assert max(uncorrected) < 0.5 < min(corrected)


def test_a_second_run_into_the_same_folder_is_refused(quick: tuple[Path, str], capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exc:
        main(["reproduce", "ceiling-target", "--quick", "--out", str(quick[0])])
    assert exc.value.code == 2
    assert "exists; give --overwrite" in capsys.readouterr().err


def test_paper_claim_is_the_papers_own_worst_error() -> None:
    assert static.paper_claim() == {"worst_rotation_deg": 6.0, "worst_position_cm": 3.0}


def test_the_demo_section_writes_its_frames(tmp_path: Path) -> None:
    text = corridor_section(tmp_path / "corridor")
    assert "20.8 m" in text and "ceiling_camera.png" in text
    for name in ("ceiling_camera.png", "corridor_top.png"):
        assert (tmp_path / "corridor" / name).stat().st_size > 1000
    import cv2

    image = cv2.imread(str(tmp_path / "corridor" / "ceiling_camera.png"))
    assert image is not None and image.shape == (720, 960, 3)
    assert np.any(np.all(image == (0, 255, 0), axis=-1))  # end A ringed (BGR green)


def _study_images(monkeypatch: pytest.MonkeyPatch, camera: dict[str, object] | None) -> list[np.ndarray]:
    """The images the illumination study renders (one seed, gain 1), with ``camera``'s overrides."""
    images: list[np.ndarray] = []
    render = CeilingCamera.render

    def keep(self: CeilingCamera, *args: object, **kwargs: object) -> tuple[np.ndarray, np.ndarray | None]:
        image, labels = render(self, *args, **kwargs)  # type: ignore[arg-type]
        images.append(image)
        return image, labels

    monkeypatch.setattr(CeilingCamera, "render", keep)
    static.illumination(1, gains=(1.0,), camera=camera)
    monkeypatch.setattr(CeilingCamera, "render", render)
    return images


def test_each_lights_camera_override_reaches_the_studys_images(monkeypatch: pytest.MonkeyPatch) -> None:
    cast, auto, glare = (dict(light.camera) for light in static.LIGHTS)
    plain = _study_images(monkeypatch, None)[0].reshape(-1, 3).astype(float)
    # a 4230-5500 K light under a 6500 K white balance: red up and blue down against green
    red_blue = _study_images(monkeypatch, cast)[0].reshape(-1, 3).astype(float)
    (r0, g0, b0), (r1, g1, b1) = plain.mean(axis=0), red_blue.mean(axis=0)
    assert r1 / g1 > 1.05 * r0 / g0 and b1 / g1 < 0.95 * b0 / g0
    # the auto white balance takes most of that cast away again
    balanced = _study_images(monkeypatch, auto)[0].reshape(-1, 3).astype(float).mean(axis=0)
    assert abs(balanced[0] / balanced[2] - r0 / b0) < 0.5 * abs(r1 / b1 - r0 / b0)
    # the lamp by the target puts a saturated glare spot on its tape
    spot = _study_images(monkeypatch, glare)[0].reshape(-1, 3)
    assert np.all(spot == 255, axis=1).sum() > np.all(plain == 255, axis=1).sum() + 20


def test_the_rows_under_a_light_are_deterministic() -> None:
    light = static.LIGHTS[0].camera
    first = static.illumination(2, gains=(0.6, 1.4), camera=light)
    again = static.illumination(2, gains=(0.6, 1.4), camera=light)
    assert first == again and any(r["fix_rate"] > 0 for r in first)


@pytest.mark.parametrize(
    ("hsv", "rgb", "n", "says"),
    [
        (0.42, 0.43, 100, "no difference beyond chance"),  # one image apart
        (0.12, 0.36, 100, "RGB ahead beyond chance"),
        (0.60, 0.30, 100, "HSV ahead beyond chance"),
        (0.12, 0.36, 10, "no difference beyond chance"),  # too few images to tell
        (1.0, 1.0, 100, "no difference beyond chance"),
    ],
)
def test_a_light_study_calls_a_colour_space_ahead_only_beyond_chance(hsv: float, rgb: float, n: int, says: str) -> None:
    from agents.papers.ceiling_target.report import _ahead

    assert _ahead(hsv, rgb, n).startswith(says)
