"""Manual check: open a sweep report in headless Chromium and save a screenshot.

Not a test (Chromium is not a dependency). Usage::

    python tests/report/check_browser.py                       # a demo report from a fake sweep
    python tests/report/check_browser.py DIR/report/report.html
    python tests/report/check_browser.py --out /tmp/report.png --height 2400

Then look at the PNG. Chromium: ``apt-get install -y chromium``.
"""

from __future__ import annotations

import argparse
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path


def demo_report(root: Path) -> Path:
    """Log a fake two-model sweep under ``root`` and write its report; returns report.html."""
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from fake_sweep import make_sweep

    from sphri.report import make_report

    truth = make_sweep(
        root / "outputs",
        root / "sweep",
        [1, 2, 3, 4, 6, 9, 13, 18, 36],
        models=["rf", "cnn_gru"],
        top={"rf": 0.85, "cnn_gru": 0.75},
        fail={("cnn_gru", 36)},
    )
    _, files, text = make_report(truth.sweep_dir)
    print(text)
    return files.html


def screenshot(html: Path, out: Path, width: int = 1200, height: int = 2400) -> Path:
    """Render ``html`` in headless Chromium (no network, no GPU) into ``out`` (PNG)."""
    exe = shutil.which("chromium") or shutil.which("chromium-browser") or shutil.which("google-chrome")
    if exe is None:
        raise SystemExit("chromium not found: apt-get install -y chromium")
    cmd = [
        exe,
        "--headless",
        "--no-sandbox",
        "--disable-gpu",
        "--disable-background-networking",
        "--disable-component-update",
        "--disable-sync",
        "--no-first-run",
        f"--screenshot={out}",
        f"--window-size={width},{height}",
        html.resolve().as_uri(),
    ]
    subprocess.run(cmd, check=True, capture_output=True, timeout=120)
    if not out.is_file() or out.stat().st_size == 0:
        raise SystemExit(f"chromium wrote no screenshot to {out}")
    return out


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("html", nargs="?", help="report.html (default: build a demo report from a fake sweep)")
    p.add_argument("--out", default="/tmp/report.png")
    p.add_argument("--width", type=int, default=1200)
    p.add_argument("--height", type=int, default=2400)
    args = p.parse_args()
    html = Path(args.html) if args.html else demo_report(Path(tempfile.mkdtemp(prefix="sphri-report-demo-")))
    print(f"screenshot: {screenshot(html, Path(args.out), args.width, args.height)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
