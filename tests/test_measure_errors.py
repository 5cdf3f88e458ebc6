"""Bad input to `photogram measure`: one line naming the file, image or
target, exit code 2, nothing written (no output folder); and gross
detections (texture, a code ring's arcs, targets cut by the image border)
rejected and counted, never labelled."""

from pathlib import Path

import cv2
import numpy as np
import pytest

from photogram.errors import InputError
from photogram.measure.detect import detect_targets
from photogram.measure.field import read_field
from photogram.measure.render import field_scene, grid_scene
from photogram_cli.main import main

# `make test-fast` leaves this module out (slow: docs/benchmarks.md, the test suite's slowest files).
pytestmark = pytest.mark.slow

SHEET = Path(__file__).resolve().parents[1] / "projects" / "camcal" / "sheet.toml"


def _field_file(folder: Path, images: Path, **changes) -> Path:
    text = SHEET.read_text()
    text = text.replace('images = "../../../shared/data/dbat/camcal/images"',
                        f'images = "{images}"')
    text = text.replace("min_diameter = 6 ", "min_diameter = 4 ")
    for old, new in changes.items():
        assert old in text
        text = text.replace(old, new)
    path = folder / "sheet.toml"
    path.write_text(text)
    return path


@pytest.fixture(scope="module")
def sheet_image():
    fld = read_field(SHEET)
    img, truth, cam = field_scene(fld, size=(640, 480), f=560.0)
    return img


@pytest.fixture
def folder(tmp_path, sheet_image):
    images = tmp_path / "images"
    images.mkdir()
    for k in range(2):
        ok, buf = cv2.imencode(".jpg", sheet_image, [cv2.IMWRITE_JPEG_QUALITY, 95])
        (images / f"img{k}.jpg").write_bytes(buf.tobytes())
    return images


def _run(capsys, args):
    code = main(["measure", *map(str, args)])
    err = capsys.readouterr().err.strip().splitlines()
    return code, err


def test_a_good_folder_is_measured(tmp_path, folder, capsys):
    out = tmp_path / "out"
    # (the report is test_report_drawings_and_pdf's)
    code, err = _run(capsys, [_field_file(tmp_path, folder), "--output", out, "--no-report"])
    assert code == 0, err
    rows = (out / "image_points.csv").read_text().splitlines()
    assert rows[1] == "station,point,x,y,sigma"
    assert len(rows) >= 2 + 2 * 95


def test_truncated_image(tmp_path, folder, capsys):
    data = (folder / "img1.jpg").read_bytes()
    (folder / "img1.jpg").write_bytes(data[: len(data) // 2])
    out = tmp_path / "out"
    code, err = _run(capsys, [_field_file(tmp_path, folder), "--output", out])
    assert code == 2 and len(err) == 1
    assert "img1.jpg" in err[0] and "truncated" in err[0]
    assert not out.exists()


def test_unreadable_image(tmp_path, folder, capsys):
    (folder / "img0.png").write_bytes(b"not an image at all")
    out = tmp_path / "out"
    code, err = _run(capsys, [_field_file(tmp_path, folder), "--output", out])
    assert code == 2 and len(err) == 1 and "img0.png" in err[0] and "decode" in err[0]
    assert not out.exists()


def test_empty_folder(tmp_path, capsys):
    empty = tmp_path / "empty"
    empty.mkdir()
    out = tmp_path / "out"
    code, err = _run(capsys, [_field_file(tmp_path, empty), "--output", out])
    assert code == 2 and len(err) == 1 and "no images" in err[0] and "empty" in err[0]
    assert not out.exists()


def test_a_field_that_matches_nothing(tmp_path, folder, capsys):
    out = tmp_path / "out"
    path = _field_file(tmp_path, folder, **{'polarity = "dark"': 'polarity = "bright"'})
    code, err = _run(capsys, [path, "--output", out])
    assert code == 2 and len(err) == 1 and "numbers no target" in err[0]
    assert "sheet.toml" in err[0]
    assert not out.exists()


def test_codes_that_disagree_with_the_layout(tmp_path, folder, capsys):
    # the description gives 1001 and 1004 each other's place
    path = _field_file(tmp_path, folder, **{"xyz = [0.0, 1.0, 0.0]": "xyz = [9.0, 9.0, 0.0]",
                                            "xyz = [1.0, 0.0, 0.0]": "xyz = [0.0, 1.0, 0.0]"})
    path.write_text(path.read_text().replace("xyz = [9.0, 9.0, 0.0]", "xyz = [1.0, 0.0, 0.0]"))
    out = tmp_path / "out"
    code, err = _run(capsys, [path, "--output", out])
    assert code == 2 and len(err) == 1
    assert "img0.jpg" in err[0] and "disagree" in err[0]
    assert not out.exists()


def test_bad_field_description(tmp_path, folder, capsys):
    path = _field_file(tmp_path, folder, **{"min_contrast = 20": "min_contrats = 20"})
    code, err = _run(capsys, [path, "--output", tmp_path / "out"])
    assert code == 2 and len(err) == 1 and "min_contrats" in err[0] and "sheet.toml:" in err[0]
    with pytest.raises(InputError, match="bits"):
        read_field(_field_file(tmp_path, folder, **{'bits = "11001100"': 'bits = "11002100"'}))


def test_earlier_results_are_not_replaced(tmp_path, folder, capsys):
    out = tmp_path / "out"
    path = _field_file(tmp_path, folder)
    assert _run(capsys, [path, "--output", out, "--no-report"])[0] == 0
    code, err = _run(capsys, [path, "--output", out])
    assert code == 2 and "--force" in err[0]
    assert _run(capsys, [path, "--output", out, "--force", "--no-report"])[0] == 0


def test_gross_detections_are_rejected_and_counted():
    """Wood-grain-like streaks, letters, a code ring's arcs, a blotch and dots cut
    by the image border: rejected with a reason, none accepted as a target."""
    def clutter(img, to_texel, ink, texel):
        def p(X, Y):
            u, v = to_texel(X, Y)
            return int(round(u)), int(round(v))
        cv2.line(img, p(-0.1, 0.66), p(0.5, 0.69), ink, max(1, int(0.008 / texel)))
        cv2.putText(img, "PHOTOGRAM", p(0.0, -0.085), cv2.FONT_HERSHEY_SIMPLEX,
                    0.03 / texel / 22, ink, max(1, int(0.004 / texel)))
        cv2.ellipse(img, p(0.65, 0.69), (int(0.04 / texel), int(0.04 / texel)), 0, 20, 160,
                    ink, max(1, int(0.012 / texel)))
        tri = np.array([p(-0.10, 0.12), p(-0.04, 0.12), p(-0.07, 0.17)], np.int32)
        cv2.fillPoly(img, [tri], ink)
        cv2.rectangle(img, p(-0.10, 0.35), p(-0.06, 0.39), ink, -1)
        cv2.rectangle(img, p(-0.17, -0.05), p(-0.12, 0.3), ink, -1)
    sc = grid_scene(size=(640, 480), f=720.0, eye=(0.45, -0.4, 0.9), target=(0.35, 0.25, 0.0),
                    shapes=clutter)
    det = detect_targets(sc.image, "dark", min_diameter=4, max_diameter=60)
    counts = det.counts()
    d = np.linalg.norm(det.xy[:, None] - sc.truth[None], axis=2)
    inside = (sc.truth[:, 0] > 12) & (sc.truth[:, 0] < 628) & (sc.truth[:, 1] > 12) \
        & (sc.truth[:, 1] < 468)
    print(counts, f"{inside.sum()} dots fully inside the image")
    # every accepted target is one of the dots; every dot well inside is found
    assert (d.min(axis=1) < 0.5).all()
    assert (d.min(axis=0)[inside] < 0.5).all()
    # the clutter and the dots cut by the border were rejected, with reasons
    assert counts["border"] >= 1
    assert counts["shape"] + counts["roundness"] + counts["fit"] >= 4
    assert len(det.rejected_xy) == sum(v for k, v in counts.items() if k != "accepted")


def test_report_drawings_and_pdf(tmp_path, folder, capsys):
    out = tmp_path / "out"
    code, err = _run(capsys, [_field_file(tmp_path, folder), "--output", out])
    assert code == 0, err
    pngs = sorted(p.name for p in (out / "images").iterdir())
    assert pngs == ["img0.png", "img1.png"]
    img = cv2.imread(str(out / "images" / "img0.png"))
    assert img is not None and max(img.shape[:2]) <= 1200
    # green rings were drawn (numbered targets)
    assert ((img[:, :, 1] > 150) & (img[:, :, 0] < 100) & (img[:, :, 2] < 100)).sum() > 100
    pdf = (out / "report.pdf").read_bytes()
    assert pdf.startswith(b"%PDF") and pdf.count(b"/Type /Page\n") + pdf.count(b"/Type /Page ") \
        + pdf.count(b"/Type/Page") >= 1
    det = (out / "detections.csv").read_text().splitlines()
    assert det[0].startswith("image,status,label,code,x,y,diameter")
    assert any(",numbered,D" in ln for ln in det)
