"""Turning a report's HTML into a self-contained page and a PDF, and a PDF page into a PNG.

The PDF route is WeasyPrint: HTML and CSS paged media laid out by Pango, in-process, with
no browser and no network. Its system libraries (Pango, HarfBuzz's subsetter) come from
Debian and are installed by the project's set-up (``scripts/install_system_packages.sh``).
Figures are embedded as ``data:`` URIs, so the HTML opens anywhere as one file; the PDF
renderer is given no other way to fetch anything.
"""
from __future__ import annotations

import base64
import mimetypes
import shutil
import subprocess
import tempfile
from pathlib import Path

_TYPES = {".png": "image/png", ".svg": "image/svg+xml", ".jpg": "image/jpeg", ".jpeg": "image/jpeg"}


def data_uri(path) -> str:
    """A figure file as a ``data:`` URI (PNG, SVG or JPEG)."""
    path = Path(path)
    kind = _TYPES.get(path.suffix.lower()) or mimetypes.guess_type(path.name)[0]
    if kind not in _TYPES.values():
        raise ValueError(f"{path}: not a figure railcal embeds (PNG, SVG or JPEG)")
    return f"data:{kind};base64,{base64.b64encode(path.read_bytes()).decode('ascii')}"


def pdf_available() -> str | None:
    """None when a PDF can be made here, else why not."""
    try:
        import weasyprint  # noqa: F401  (loads Pango through cffi)
    except (ImportError, OSError) as e:
        return f"WeasyPrint cannot load ({e}); run scripts/install_system_packages.sh"
    return None


def html_to_pdf(html: str, out) -> Path:
    """Lay out ``html`` (self-contained) as a PDF at ``out``, written whole or not at all."""
    import weasyprint
    import weasyprint.urls

    out = Path(out)
    tmp = out.with_name(out.name + ".part")
    try:
        # a self-contained page: data: URIs only, and a reference to anything else fails
        fetcher = weasyprint.urls.URLFetcher(allowed_protocols=("data",), fail_on_errors=True)
        try:
            weasyprint.HTML(string=html, url_fetcher=fetcher).write_pdf(tmp)
        except weasyprint.urls.FatalURLFetchingError as e:  # a BaseException: made an ordinary error here
            raise ValueError(f"the report is not self-contained: {e}") from None
        tmp.replace(out)
    finally:
        tmp.unlink(missing_ok=True)
    return out


def pdf_page_png(pdf, out_stem, *, page: int = 1, dpi: int = 60) -> Path:
    """Page ``page`` of ``pdf`` rendered to ``out_stem``.png by poppler's pdftoppm, for a
    person (or a test) to look at."""
    if shutil.which("pdftoppm") is None:
        raise RuntimeError("pdftoppm (Debian poppler-utils) is not installed; run scripts/install_system_packages.sh")
    subprocess.run(["pdftoppm", "-png", "-r", str(dpi), "-f", str(page), "-l", str(page), "-singlefile",
                    str(pdf), str(out_stem)], check=True, capture_output=True, timeout=120)
    return Path(f"{out_stem}.png")


#: Debian's Chromium, headless, offline and with no profile of its own: its background
#: services would try the network, which a report must never need
CHROMIUM_FLAGS = ("--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                  "--disable-background-networking", "--disable-component-update", "--disable-sync",
                  "--hide-scrollbars", "--host-resolver-rules=MAP * ~NOTFOUND")


def chromium() -> str | None:
    """The headless browser's path (Debian's chromium), or None."""
    return shutil.which("chromium") or shutil.which("chromium-browser")


def html_screenshot(html, out, *, width: int = 1100, height: int = 1500) -> Path:
    """The top ``width`` x ``height`` pixels of the HTML file ``html`` as headless Chromium
    shows them, at ``out`` (PNG): the page as a person opening it sees it first."""
    browser = chromium()
    if browser is None:
        raise RuntimeError("Chromium is not installed (Debian package chromium); "
                           "run scripts/install_system_packages.sh")
    out = Path(out)
    with tempfile.TemporaryDirectory() as profile:
        subprocess.run([browser, *CHROMIUM_FLAGS, f"--user-data-dir={profile}", f"--window-size={width},{height}",
                        f"--screenshot={out.resolve()}", Path(html).resolve().as_uri()],
                       check=True, capture_output=True, timeout=120)
    if not out.is_file():
        raise RuntimeError(f"Chromium wrote no screenshot of {html}")
    return out
