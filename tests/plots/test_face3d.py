"""The interactive 3-D page: regions from the coefficients, a self-contained page that is the
same bytes on a rebuild, and in a real headless browser (Debian's chromium, driven by
Playwright): no console error, the dataset switcher, and a hover card with the label."""

import os
import shutil

import numpy as np
import pytest

from facemotion.errors import InputError
from facemotion.plots.face3d import DIV_ID, FaceView, face_page, regions_from_coefficients

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")


def views():
    rng = np.random.default_rng(0)
    out = []
    for name, n in (("S1", 12), ("S2a", 9)):
        labels = [f"{name}_m{j}" for j in range(n)]
        neutral = np.column_stack([rng.uniform(-50, 50, n), rng.uniform(-80, 60, n),
                                   rng.uniform(0, 20, n)])
        coef = {labels[0]: {m: 1.0 for m in labels[2:6]}, labels[1]: {m: 0.5 for m in labels[2:]}}
        out.append(FaceView(name, labels, neutral, regions_from_coefficients(labels, coef),
                            list(range(1, n + 1)), labels[:2],
                            np.r_[0.0, 0.0, rng.uniform(0.2, 1.0, n - 2)],
                            np.r_[0.0, 0.0, np.full(n - 2, 0.1)],
                            np.r_[0.0, 0.0, np.full(n - 2, 1.1)]))
    return out


def test_regions_follow_the_largest_coefficient():
    labels = ["a", "b", "c", "d"]
    coef = {"a": {"c": 0.9, "d": -0.1}, "b": {"c": 0.2, "d": -0.8}}
    assert regions_from_coefficients(labels, coef) == ["a", "b", "a", "b"]


def test_page_is_self_contained_and_reproducible():
    html = face_page(views(), "study")
    assert html == face_page(views(), "study")
    assert "<script src=" not in html and "plotly.js v" in html   # plotly.js inline
    assert f'id="{DIV_ID}"' in html and "S2a_m8" in html and "pivot order: 12" in html
    with pytest.raises(InputError, match="no dataset"):
        face_page([], "x")
    with pytest.raises(InputError, match="not among its labels"):
        FaceView("x", ["a"], np.zeros((1, 3)), ["a"], [1], ["zz"])


#: the screen position of every point of the first trace, from the scene's camera matrices
PROJECT = """() => {
  const gd = document.getElementById('DIV_ID');
  const scene = gd._fullLayout.scene._scene, p = scene.glplot.cameraParams, s = scene.dataScale;
  const r = scene.glplot.canvas.getBoundingClientRect(), tr = gd._fullData[0], out = [];
  for (let i = 0; i < tr.x.length; i++) {
    let v = [tr.x[i] * s[0], tr.y[i] * s[1], tr.z[i] * s[2], 1];
    for (const M of [p.model, p.view, p.projection]) {
      const w = [0, 0, 0, 0];
      for (let a = 0; a < 4; a++) for (let b = 0; b < 4; b++) w[a] += M[b * 4 + a] * v[b];
      v = w;
    }
    out.push([r.left + (v[0] / v[3] + 1) / 2 * r.width, r.top + (1 - v[1] / v[3]) / 2 * r.height]);
  }
  return out;
}""".replace("DIV_ID", DIV_ID)


def test_page_in_a_headless_browser(tmp_path):
    if CHROMIUM is None:
        if os.environ.get("FACEMOTION_REQUIRE_BROWSER"):
            pytest.fail("chromium is not installed (apt-get install chromium)")
        pytest.skip("chromium is not installed (CI installs it: .ci/run)")
    from playwright.sync_api import sync_playwright

    page_file = tmp_path / "face.html"
    page_file.write_text(face_page(views(), "study"), encoding="utf-8")
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, headless=True,
                                    args=["--no-sandbox", "--use-angle=swiftshader",
                                          "--enable-unsafe-swiftshader"])
        try:
            page = browser.new_page(viewport={"width": 1000, "height": 800})
            errors = []
            page.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
            page.on("pageerror", lambda e: errors.append(str(e)))
            page.goto(page_file.as_uri())
            page.wait_for_selector(f"#{DIV_ID} .gl-container canvas", timeout=30000)
            page.wait_for_timeout(500)
            hovered = None
            for x, y in page.evaluate(PROJECT)[2:]:     # secondary markers of S1
                page.mouse.move(x, y)
                try:
                    page.wait_for_selector(f"#{DIV_ID} .hovertext", timeout=1500)
                except Exception:  # noqa: BLE001 - playwright's TimeoutError: try the next
                    continue
                hovered = page.text_content(f"#{DIV_ID} .hovertext")   # SVG text, no breaks
                break
            assert hovered is not None, "no hover card on any marker"
            assert hovered.startswith("S1_m")
            assert "pivot order:" in hovered and "held-out error:" in hovered
            # the dataset switcher shows the other dataset's markers
            page.click(f"#{DIV_ID} .updatemenu-header")
            page.wait_for_selector(f"#{DIV_ID} .updatemenu-dropdown-button", timeout=5000)
            page.evaluate(f"""() => {{
                const items = [...document.querySelectorAll(
                    '#{DIV_ID} .updatemenu-dropdown-button')];
                const item = items.find(b => b.textContent.trim() === 'S2a');
                item.dispatchEvent(new MouseEvent('click', {{bubbles: true}}));
            }}""")
            page.wait_for_timeout(500)
            visible = page.evaluate(f"() => document.getElementById('{DIV_ID}')"
                                    ".data.map(t => t.visible)")
            assert visible == [False, False, True, True]
            assert errors == []
        finally:
            browser.close()
