"""Render an HTML report in headless Chromium: check what a reader would see, take a screenshot.

Chromium (Debian's ``chromium`` package) is not a Python dependency; the tests that use it
skip, saying so, where it is not installed.
"""

from __future__ import annotations

import json
import shutil
import subprocess
import tempfile
from pathlib import Path

CHECK_SCRIPT = """
<script>
window.addEventListener('load', () => {
  const figures = [...document.images].map((img) => {
    const c = document.createElement('canvas');
    c.width = img.naturalWidth; c.height = img.naturalHeight;
    let inked = 0;
    if (c.width && c.height) {
      const ctx = c.getContext('2d'); ctx.drawImage(img, 0, 0);
      const px = ctx.getImageData(0, 0, c.width, c.height).data;
      for (let i = 0; i < px.length; i += 4) if (px[i] < 200 || px[i+1] < 200 || px[i+2] < 200) inked++;
    }
    return {alt: img.alt, width: img.naturalWidth, height: img.naturalHeight,
            shown_width: img.getBoundingClientRect().width, inked: inked / Math.max(1, c.width * c.height)};
  });
  const tables = [...document.querySelectorAll('table')].map((t) => ({
    headers: [...t.rows[0].cells].map((c) => c.textContent.trim()),
    header_cells: [...t.rows[0].cells].map((c) => c.tagName),
    rows: t.rows.length - 1,
    wrapped_numbers: [...t.querySelectorAll('td')].filter((td) =>
      /^[-+]?[0-9.,]+(e[-+]?[0-9]+)?\\s?%?$/.test(td.textContent.trim()) && td.getClientRects().length &&
      td.getBoundingClientRect().height > 1.8 * parseFloat(getComputedStyle(td).lineHeight || 18)).length,
  }));
  const pre = document.createElement('pre');
  pre.id = 'phid-check';
  pre.textContent = JSON.stringify({figures, tables, width: document.documentElement.scrollWidth});
  document.body.appendChild(pre);
});
</script>
"""


def chromium() -> str | None:
    for name in ("chromium", "chromium-browser", "google-chrome"):
        path = shutil.which(name)
        if path:
            return path
    return None


def _run(args: list[str], timeout: float = 120) -> subprocess.CompletedProcess[str]:
    exe = chromium()
    assert exe is not None, "no Chromium on this machine"
    with tempfile.TemporaryDirectory() as profile:
        base = [exe, "--headless", "--no-sandbox", "--disable-gpu", "--hide-scrollbars", f"--user-data-dir={profile}"]
        return subprocess.run(base + args, capture_output=True, text=True, timeout=timeout, check=False)


def _rendered(report: Path, script: str, marker: str) -> str | None:
    """The text a probe script left in ``<pre id=marker>`` after Chromium loaded the page, or None."""
    with tempfile.TemporaryDirectory() as tmp:
        page = Path(tmp) / report.name
        page.write_text(report.read_text(encoding="utf-8").replace("</body>", script + "</body>"))
        done = _run(["--window-size=1280,2000", "--virtual-time-budget=20000", "--dump-dom", page.as_uri()])
    start = done.stdout.find(f'<pre id="{marker}">')
    if start < 0:
        return None
    import html

    return html.unescape(done.stdout[start + len(f'<pre id="{marker}">') : done.stdout.index("</pre>", start)])


def inspect(report: Path) -> dict:
    """What Chromium rendered: every figure's size and share of inked pixels, every table's headers."""
    text = _rendered(report, CHECK_SCRIPT, "phid-check")
    if text is None:
        raise AssertionError(f"Chromium rendered no check for {report}")
    return json.loads(text)


def screenshot(report: Path, png: Path, width: int = 1280, height: int | None = None) -> Path:
    """A screenshot of the page as Chromium lays it out (the whole page when ``height`` is None)."""
    if height is None:
        height = _page_height(report)
    png.parent.mkdir(parents=True, exist_ok=True)
    done = _run([f"--window-size={width},{height}", f"--screenshot={png.resolve()}", report.resolve().as_uri()])
    if not png.exists():
        raise AssertionError(f"Chromium wrote no screenshot of {report}: {done.stderr[-500:]}")
    return png


def _page_height(report: Path) -> int:
    probe = (
        "<script>window.addEventListener('load',()=>{const p=document.createElement('pre');p.id='phid-h';"
        "p.textContent=document.documentElement.scrollHeight;document.body.appendChild(p);});</script>"
    )
    text = _rendered(report, probe, "phid-h")
    return 4000 if text is None else int(text) + 40


def assert_readable(report: Path, figures: int) -> dict:
    """Every figure a non-blank image shown on the page, every table its headers, no number wrapped,
    nothing off the right edge of a 1280-pixel window."""
    seen = inspect(report)
    assert len(seen["figures"]) == figures, [f["alt"] for f in seen["figures"]]
    for fig in seen["figures"]:
        assert fig["width"] > 300 and fig["height"] > 200 and fig["shown_width"] > 300, fig
        assert fig["inked"] > 0.01, f"{fig['alt']}: an almost blank figure"
    assert seen["tables"]
    for table in seen["tables"]:
        assert table["rows"] > 0 and all(table["headers"]) and set(table["header_cells"]) == {"TH"}, table
        assert table["wrapped_numbers"] == 0, table
    assert seen["width"] <= 1280, f"{report}: {seen['width']} px wide"
    return seen
