"""Screenshots of the live viewer for docs/viewer.md, and its frame rate while dragging.

    python scripts/make_viewer_images.py                 # writes docs/viewer*.png
    python scripts/make_viewer_images.py --measure       # fps while dragging, no images

Drives Debian's headless Chromium (/usr/bin/chromium) through Playwright, as the tests do, against
an in-process server on the built-in demo. The measurement drags continuously for ``--seconds``
(pointer events at 60 Hz) in a ``--size`` view and reports the frames the page drew per second and
the previews the host rendered per second (the session's preview plan: 4 spp at 1/8 of the view's size).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from playwright.sync_api import sync_playwright

from warp_spt.viewer.server import ViewerServer
from warp_spt.viewer.session import open_session

CHROMIUM = "/usr/bin/chromium"
ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
        "--disable-background-networking", "--disable-component-update", "--disable-sync"]
DOCS = Path(__file__).resolve().parents[1] / "docs"
WAIT_MS = 600_000


def dataset(page) -> dict:
    return page.evaluate("() => ({...document.querySelector('.wspt').dataset})")


def wait(page, condition: str) -> None:
    page.wait_for_function(f"() => {{ const d = document.querySelector('.wspt')?.dataset; return d && ({condition}); }}",
                           timeout=WAIT_MS)


def centre(page) -> tuple[float, float]:
    box = page.locator(".wspt canvas").bounding_box()
    return box["x"] + box["width"] / 2, box["y"] + box["height"] / 2


def drag_for(page, seconds: float, px_per_event: float = 2.0, hold: bool = False) -> int:
    """Drag right and back at 60 events per second for ``seconds``; returns the frames drawn."""
    x, y = centre(page)
    page.mouse.move(x, y)
    page.mouse.down()
    start_frames = int(dataset(page).get("frames", 0))
    t0, k = time.perf_counter(), 0
    while time.perf_counter() - t0 < seconds:
        k += 1
        swing = ((k // 90) % 2) * 2 - 1                       # change direction every 1.5 s
        x -= swing * px_per_event
        page.mouse.move(x, y)
        time.sleep(1 / 60)
    frames = int(dataset(page)["frames"]) - start_frames
    if not hold:
        page.mouse.up()
    return frames


def screenshot(page, name: str) -> None:
    path = DOCS / name
    page.locator(".wspt").screenshot(path=str(path))
    print(f"wrote {path}")


def images(page, session) -> None:
    wait(page, f"d.mode === 'refine' && Number(d.spp) >= 256 && Number(d.version) >= {session.version}")
    screenshot(page, "viewer.png")
    drag_for(page, 1.0, px_per_event=1.5, hold=True)          # mid-drag: the low-resolution preview
    screenshot(page, "viewer_moving.png")
    page.mouse.up()
    page.click(".wspt-copy")
    page.check(".wspt input[type=checkbox]")                  # the error map
    wait(page, f"d.mode === 'refine' && Number(d.spp) >= 64 && Number(d.version) >= {session.version}")
    screenshot(page, "viewer_error_map.png")


def measure(page, seconds: float, size: tuple[int, int]) -> None:
    wait(page, "d.mode === 'refine'")
    drag_for(page, 2.0)                                       # warm-up: kernels, JIT, caches
    wait(page, "d.mode === 'refine'")
    frames = drag_for(page, seconds, hold=True)
    last = dataset(page)
    page.mouse.up()
    print(f"view {size[0]}x{size[1]}, previews {last['size']} at 1 spp, dragging for {seconds:g} s: "
          f"{frames / seconds:.1f} frames/s drawn by the page (last second: {last['fps']}/s)")


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--measure", action="store_true", help="measure fps while dragging instead of writing images")
    p.add_argument("--seconds", type=float, default=10.0, help="length of the measured drag")
    p.add_argument("--size", type=int, nargs=2, default=(512, 384), metavar=("W", "H"), help="view size")
    ns = p.parse_args()
    size = tuple(ns.size) if ns.measure else (384, 288)
    session = open_session(width=size[0], height=size[1], max_spp=256)
    server = ViewerServer(session)
    url = server.start_thread()
    try:
        with sync_playwright() as pw:
            browser = pw.chromium.launch(executable_path=CHROMIUM, args=ARGS, headless=True)
            page = browser.new_page(viewport={"width": 1000, "height": 760}, device_scale_factor=1)
            page.goto(url)
            if ns.measure:
                measure(page, ns.seconds, size)
            else:
                images(page, session)
            browser.close()
    finally:
        server.stop_thread()
        session.close()


if __name__ == "__main__":
    main()
