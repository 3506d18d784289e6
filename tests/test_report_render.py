"""The report's rendering route: a self-contained HTML page with an embedded figure becomes a
PDF, and the PDF's first page a PNG a person can look at."""
from __future__ import annotations

import shutil
import subprocess

import matplotlib
import numpy as np
import pytest

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from conftest import axes_without_units  # noqa: E402
from railcal.report.render import (chromium, data_uri, html_screenshot, html_to_pdf, pdf_available,  # noqa: E402
                                   pdf_page_png)

WHY_NOT = pdf_available()


def _page(tmp_path, body_extra: str = "") -> str:
    fig, ax = plt.subplots(figsize=(4, 2.5))
    f = np.geomspace(0.5, 80, 200)
    ax.semilogx(f, 1 / (1 + (f / 8) ** 2))
    ax.set_xlabel("frequency [Hz]")
    ax.set_ylabel("weighting [-]")
    png = tmp_path / "w.png"
    fig.savefig(png, dpi=80)
    plt.close(fig)
    return (f"<html><head><meta charset='utf-8'><title>t</title></head><body><h1>Sign-off report</h1>"
            f"<table><tr><td>N_MV</td><td>1.23</td></tr></table><img src='{data_uri(png)}'/>{body_extra}"
            "</body></html>")


def test_a_figure_is_embedded_as_a_data_uri(tmp_path):
    html = _page(tmp_path)
    assert "data:image/png;base64," in html and "w.png" not in html
    with pytest.raises(ValueError, match="not a figure"):
        data_uri(tmp_path / "notes.txt")


@pytest.mark.skipif(WHY_NOT is not None, reason=str(WHY_NOT))
def test_the_pdf_carries_the_text_and_its_first_page_is_not_blank(tmp_path):
    pdf = html_to_pdf(_page(tmp_path), tmp_path / "report.pdf")
    assert pdf.read_bytes()[:5] == b"%PDF-" and not (tmp_path / "report.pdf.part").exists()
    if shutil.which("pdftotext") is None or shutil.which("pdftoppm") is None:
        pytest.skip("poppler-utils (pdftotext, pdftoppm) not installed: run scripts/install_system_packages.sh")
    text = subprocess.run(["pdftotext", str(pdf), "-"], capture_output=True, text=True, check=True).stdout
    assert "Sign-off report" in text and "1.23" in text
    png = pdf_page_png(pdf, tmp_path / "page")
    image = plt.imread(png)
    assert image.shape[0] > 100 and np.ptp(image[..., :3]) > 0.5  # ink on the page: text and the figure


@pytest.mark.skipif(WHY_NOT is not None, reason=str(WHY_NOT))
def test_a_page_that_reaches_outside_itself_is_refused_and_nothing_is_left(tmp_path):
    with pytest.raises(ValueError, match="not self-contained.*example.invalid"):
        html_to_pdf(_page(tmp_path, "<img src='http://example.invalid/x.png'/>"), tmp_path / "r.pdf")
    assert not (tmp_path / "r.pdf").exists() and not (tmp_path / "r.pdf.part").exists()


@pytest.mark.skipif(chromium() is None, reason="Chromium not installed: run scripts/install_system_packages.sh")
def test_the_html_page_as_headless_chromium_shows_it(tmp_path):
    page = tmp_path / "report.html"
    page.write_text(_page(tmp_path))
    png = html_screenshot(page, tmp_path / "shot.png", width=600, height=500)
    image = plt.imread(png)[..., :3]
    assert image.shape[:2] == (500, 600)
    dark = image.mean(axis=2) < 0.5
    assert dark[:80].any(), "no heading at the top of the page"
    assert dark[80:].sum() > 500, "no table or figure below it"


def test_an_axis_without_a_unit_is_named_and_a_shared_one_is_labelled_once():
    fig, axes = plt.subplots(2, 2, sharex="col")
    for ax in axes.ravel():
        ax.plot([1, 2], [3, 4])
        ax.set_ylabel("acceleration [m/s^2]")
    axes[0, 0].set_title("top left")
    axes[0, 1].set_ylabel("acceleration")  # no unit
    for ax in axes[-1]:
        ax.set_xlabel("frequency [Hz]")
    # a colorbar's long side is an axis like any other; its short side has no ticks and needs no label
    fig.colorbar(axes[0, 0].imshow(np.eye(2)), ax=axes[0, 0], label="level [-]")
    assert axes_without_units(fig) == ["'untitled': y ('acceleration')"]
    axes[1, 0].set_xlabel("frequency")
    assert "'top left': x ('')" in axes_without_units(fig)
    plt.close(fig)
    fig, ax = plt.subplots()  # an axis of names (a MAC matrix's modes) has no unit, but a label
    ax.imshow(np.eye(2))
    ax.set_xticks(range(2), ["bounce", "pitch"])
    ax.set_yticks(range(2), ["bounce", "pitch"])
    ax.set_ylabel("identified mode")
    assert axes_without_units(fig) == ["'untitled': x ('')"]
    plt.close(fig)
