"""The README's studio figure: start `artformer studio` on the shipped model, type a prompt
in headless Chromium, wait for the object and save a screenshot.

    python scripts/studio_screenshot.py --out docs/figures/studio.png \
        --prompt "a storage cabinet with two drawers and a door on the left"

Needs Debian's `chromium`. The browser may reach 127.0.0.1 only.
"""
from __future__ import annotations

import argparse
import shutil
import socket
import tempfile
import time


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", default="docs/figures/studio.png")
    ap.add_argument("--prompt", default="a storage cabinet with two drawers and a door on the left")
    ap.add_argument("--openness", type=float, default=0.5, help="openness slider value shown")
    a = ap.parse_args(argv)

    from playwright.sync_api import sync_playwright

    from model.app.studio import serve_studio
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    server, _ = serve_studio(port=port, out_dir=tempfile.mkdtemp(prefix="studio_"))
    try:
        with sync_playwright() as p:
            b = p.chromium.launch(executable_path=shutil.which("chromium"), headless=True,
                                  args=["--use-angle=swiftshader", "--enable-unsafe-swiftshader",
                                        "--no-sandbox",
                                        "--host-resolver-rules=MAP * ~NOTFOUND , EXCLUDE 127.0.0.1"])
            page = b.new_page(viewport={"width": 1280, "height": 800})
            page.route("**/*", lambda r: r.continue_() if r.request.url.startswith(
                ("http://127.0.0.1", "ws://127.0.0.1", "data:", "blob:")) else r.abort())
            page.goto(f"http://127.0.0.1:{port}")
            page.wait_for_selector("canvas")
            page.get_by_role("textbox").fill(a.prompt)
            page.get_by_role("button", name="Generate", exact=True).click()
            page.get_by_role("button", name="Download zip").and_(
                page.locator(":enabled")).wait_for(timeout=300000)
            box = page.locator("input[inputmode=decimal]").first
            box.fill(str(a.openness))
            box.press("Enter")
            time.sleep(4)
            for close in page.locator("button.mantine-Notification-closeButton").all():
                close.click()
            time.sleep(1)
            page.screenshot(path=a.out)
            b.close()
    finally:
        server.stop()
    print(a.out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
