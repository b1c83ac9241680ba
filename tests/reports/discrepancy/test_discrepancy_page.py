"""The discrepancy page as QA reads it (issue 31): discrepancy.html, written by
``gyrocal discrepancy`` from a log with two hidden effects, rendered by a real headless Chromium.

What a reader must see: a unit on every gap metric, each named effect's own before/after panel
on screen and not drawn over another's, and the separating experiment wrapped inside the page
(no sideways scrolling). With ``GYROCAL_SCREENSHOTS=docs`` the test also writes
docs/discrepancy-page.png, the image the README shows. Chromium and chromedriver come from
Debian (``make browser``); missing, the test FAILS.
"""

from __future__ import annotations

import os
import re
from pathlib import Path

import discrepancy_scenarios as scenarios
import pytest
from selenium.webdriver.common.by import By

from gyrocal.cli import main
from gyrocal.models.gyro_model import dump_model
from tests.support.browser import headless_chromium

PROFILE = scenarios.procedure_profile(3600.0, 5.0)


@pytest.fixture(scope="module")
def page(tmp_path_factory) -> Path:
    """discrepancy.html of a 1 h, 5 Hz log hiding a temperature hysteresis and an SF asymmetry."""
    folder = tmp_path_factory.mktemp("discrepancy-page")
    dump_model(scenarios.nominal_model(), folder / "nominal.yaml")
    hidden = [scenarios.sized_effect("temp_hysteresis", 15.0, PROFILE, max_bins=1000),
              scenarios.sized_effect("sf_asymmetry", 15.0, PROFILE, max_bins=1000)]
    scenarios.write_log(scenarios.simulate_log(PROFILE, hidden, 31), folder / "log.csv")
    assert main(["discrepancy", "--model", str(folder / "nominal.yaml"), "--measured",
                 str(folder / "log.csv"), "--out", str(folder / "out"), "--seed", "31"]) == 0
    return folder / "out" / "discrepancy.html"


def _overlap(a: dict, b: dict) -> bool:
    return (a["x"] < b["x"] + b["width"] and b["x"] < a["x"] + a["width"]
            and a["y"] < b["y"] + b["height"] and b["y"] < a["y"] + a["height"])


@pytest.mark.timeout(120)
def test_discrepancy_page_shows_units_both_panels_and_wraps(page: Path) -> None:
    browser = headless_chromium()
    try:
        browser.get(page.resolve().as_uri())
        assert "Found: " in browser.find_element(By.CLASS_NAME, "verdict").text
        # every gap metric has a unit, in its own column, and a header over every column
        table = browser.find_element(By.ID, "gap-metrics")
        header = [th.text for th in table.find_elements(By.CSS_SELECTOR, "tr th")]
        rows = table.find_elements(By.CSS_SELECTOR, "tr")[1:]
        assert rows and header[:2] == ["metric", "unit"]
        for row in rows:
            cells = [td.text for td in row.find_elements(By.TAG_NAME, "td")]
            assert len(cells) == len(header), (header, cells)
            assert cells[1].strip(), f"no unit for {cells[0]}"
        # each named effect has a panel of its own, on screen, not under another's
        named = [td.text for td in browser.find_elements(By.CSS_SELECTOR, "#named tr td:first-child")]
        assert sorted(named) == ["sf_asymmetry", "temp_hysteresis"]
        panels = browser.find_elements(By.CSS_SELECTOR, "figure.effect-gap")
        assert sorted(p.get_attribute("data-effect") for p in panels) == sorted(named)
        rects = []
        for panel in panels:
            image = panel.find_element(By.TAG_NAME, "img")
            assert panel.is_displayed() and browser.execute_script(
                "return arguments[0].complete && arguments[0].naturalWidth > 0", image)
            caption = panel.find_element(By.TAG_NAME, "figcaption").text
            assert panel.get_attribute("data-effect") in caption and "before" in caption
            assert re.search(r"its own gap in \S+", caption), caption
            rects.append(panel.rect)
            assert rects[-1]["width"] > 150 and rects[-1]["height"] > 150, rects[-1]
        assert not any(_overlap(a, b) for i, a in enumerate(rects) for b in rects[i + 1:]), rects
        # the separating experiment wraps: nothing is wider than the window
        experiments = browser.find_elements(By.CSS_SELECTOR, "pre.experiment")
        assert experiments, "no separating experiment on the page"
        for pre in experiments:
            assert pre.is_displayed()
            assert browser.execute_script(
                "return arguments[0].scrollWidth <= arguments[0].clientWidth", pre)
        scroll_px, client_px = browser.execute_script(
            "const d = document.documentElement; return [d.scrollWidth, d.clientWidth];")
        assert scroll_px <= client_px, f"the page scrolls sideways: {scroll_px} > {client_px} px"
        if os.environ.get("GYROCAL_SCREENSHOTS"):
            height_px = browser.execute_script("return document.documentElement.scrollHeight")
            browser.set_window_size(1400, min(int(height_px) + 120, 6000))
            browser.save_screenshot(str(Path(os.environ["GYROCAL_SCREENSHOTS"])
                                        / "discrepancy-page.png"))
    finally:
        browser.quit()
