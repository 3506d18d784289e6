"""`railcal report`: the sign-off report of a results folder holds the results' own numbers,
is one self-contained page, and lays out as a PDF a person can read."""
from __future__ import annotations

import json
import re
import shutil
import subprocess
from html.parser import HTMLParser

import pytest

from railcal.cli import main
from railcal.report.build import number
from railcal.report.render import pdf_available


@pytest.fixture(scope="module")
def results(synthetic_campaign, synthetic_identification, tmp_path_factory):
    """A results folder as `railcal run` lays it out: identification, calibration,
    validation and diagnosis of the session's synthetic campaign."""
    root, _ = synthetic_campaign
    out = tmp_path_factory.mktemp("results")
    shutil.copy(synthetic_identification[0], out / "identification.json")
    for plot in synthetic_identification[0].parent.glob("*.png"):
        shutil.copy(plot, out / plot.name)
    steps = [["calibrate", str(root), "--identification", str(out / "identification.json"),
              "--out", str(out / "calibration.json")],
             ["validate", str(root), "--calibration", str(out / "calibration.json"), "--out", str(out / "validation.json")],
             ["diagnose", str(root), "--calibration", str(out / "calibration.json"), "--out", str(out / "diagnosis.json")]]
    for argv in steps:
        assert main(argv + ["--quiet"]) == 0, argv
    return out


class _Cells(HTMLParser):
    """(data-json path, text) of every element carrying data-json, and every src/href."""

    def __init__(self):
        super().__init__()
        self.cells, self.links, self._open = [], [], []

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        self.links += [a[k] for k in ("src", "href") if k in a]
        self._open.append((a.get("data-json"), []))

    def handle_endtag(self, tag):
        path, text = self._open.pop()
        if path is not None:
            self.cells.append((path, "".join(text).strip()))
        if self._open:
            self._open[-1][1].extend(text)

    def handle_data(self, data):
        if self._open:
            self._open[-1][1].append(data)


def _at(results, path: str):
    step, *keys = path.split("/")
    x = json.loads((results / f"{step}.json").read_text())
    for k in keys:
        x = x[int(k)] if isinstance(x, list) else x[k]
    return x


def test_every_number_in_the_reports_tables_is_its_results(results, capsys):
    assert main(["report", str(results)]) == 0
    assert "wrote" in capsys.readouterr().out
    parser = _Cells()
    parser.feed((results / "report.html").read_text())
    assert len(parser.cells) > 30
    steps = {path.split("/")[0] for path, _ in parser.cells}
    assert steps == {"identification", "calibration", "validation", "diagnosis"}
    for path, text in parser.cells:  # the value itself, to the figures shown (4, or 2 for tiny agreements)
        assert any(text == number(_at(results, path), digits) for digits in (2, 4)), (path, text)
    # one file: every figure embedded, nothing fetched from elsewhere
    assert parser.links and all(link.startswith("data:image/") for link in parser.links)
    html = (results / "report.html").read_text()
    assert "Ride comfort" in html and "crosscheck <span class=\"absent\">(not run)</span>" in html


@pytest.mark.skipif(pdf_available() is not None, reason=str(pdf_available()))
def test_the_pdf_report_reads_as_its_html(results):
    assert main(["report", str(results), "--pdf", "--quiet"]) == 0
    pdf = results / "report.pdf"
    if shutil.which("pdftotext") is None:
        pytest.skip("poppler-utils not installed: run scripts/install_system_packages.sh")
    text = subprocess.run(["pdftotext", str(pdf), "-"], capture_output=True, text=True, check=True).stdout
    assert "Sign-off" in text and "Identification" in text and "Diagnosis" in text
    cal = json.loads((results / "calibration.json").read_text())
    assert number(cal["fit"][0]["model_hz"]) in text
    assert re.search(r"page 1 of \d+", text)


def test_report_refuses_a_folder_without_results_and_writes_nothing(tmp_path, capsys):
    assert main(["report", str(tmp_path / "missing")]) == 2
    assert "not a results folder" in capsys.readouterr().err
    assert main(["report", str(tmp_path)]) == 2
    assert "no step result" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []
    (tmp_path / "diagnosis.json").write_text("{not json")
    assert main(["report", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert "diagnosis.json" in err and not (tmp_path / "report.html").exists()


def test_the_verdict_follows_the_criteria_given(results, tmp_path, capsys):
    strict = tmp_path / "strict.toml"
    strict.write_text('[[criterion]]\nname = "a perfect fit"\nresult = "calibration"\nvalue = "max_error_pct"\n'
                      'at_most = -1.0\n')
    assert main(["report", str(results), "--criteria", str(strict), "--quiet"]) == 0
    html = (results / "report.html").read_text()
    assert "Not accepted: 1 of 1 criteria failed (a perfect fit)." in html
    assert main(["report", str(results), "--quiet"]) == 0
    assert "(railcal's default criteria)" in (results / "report.html").read_text()
    capsys.readouterr()
    strict.write_text('[[criterion]]\nname = "x"\nresult = "nowhere"\nvalue = "v"\nat_most = 1\n')
    before = (results / "report.html").stat().st_mtime_ns
    assert main(["report", str(results), "--criteria", str(strict)]) == 2
    assert "criterion[0].result" in capsys.readouterr().err
    assert (results / "report.html").stat().st_mtime_ns == before


def test_an_excitation_tests_report_shows_its_noise_floors_and_standard_errors(tmp_path, capsys):
    """A results folder holding only a shaker test's identification: the data-quality table
    gives every channel's noise floor, the modes their standard errors, each the JSON's number."""
    from conftest import COARSE_BOX_ORDERS
    from calibration.truth.excitation import ExcitationSettings, synth_excitation

    synth_excitation(tmp_path / "shaker", seed=2,
                     settings=ExcitationSettings(runs=1, duration=120.0, order_change=COARSE_BOX_ORDERS))
    out = tmp_path / "results"
    out.mkdir()
    assert main(["identify", str(tmp_path / "shaker"), "--out", str(out / "identification.json"), "--quiet"]) == 0
    assert main(["report", str(out), "--quiet"]) == 0
    parser = _Cells()
    parser.feed((out / "report.html").read_text())
    for path, text in parser.cells:
        assert any(text == number(_at(out, path), digits) for digits in (2, 4)), (path, text)
    paths = {path for path, _ in parser.cells}
    ident = json.loads((out / "identification.json").read_text())
    floors = ident["data"]["noise_floors"]
    assert len(floors) == 1 + len(ident["sensors"])  # the force and every accelerometer
    assert all(f"identification/data/noise_floors/{k}/asd_si_per_sqrt_hz" in paths for k in range(len(floors)))
    assert ident["modes"] and all(f"identification/modes/{k}/frequency_std_hz" in paths
                                  for k, m in enumerate(ident["modes"]) if m["frequency_std_hz"] is not None)
    assert sum(m["frequency_std_hz"] is not None for m in ident["modes"]) >= len(ident["modes"]) - 1
    assert "Not in this report yet" not in (out / "report.html").read_text()
