"""The live page in a real headless Chromium, watching a real simulated run advance and fault.

The run goes through ``gyrocal run --sim`` in this process (a thread); it is
held paused before its first step by the operator's PAUSE file, so the page
can be seen PAUSED, then let go; an injected interlock opening at
T02.sf.+20dps faults it. The page reads only the run folder. Chromium and
chromedriver come from Debian (``make browser``); missing, this test FAILS:
a browser test that skips is a check not made.
"""

from __future__ import annotations

import os
import threading
from pathlib import Path
from typing import Any

from selenium.webdriver.common.by import By
from selenium.webdriver.support.ui import WebDriverWait

from gyrocal.cli import EXIT_FAULT, main
from gyrocal.orchestrator.watch.server import WatchServer
from tests.support.browser import headless_chromium

PATIENCE_S = 120   # an upper bound for a loaded CI machine, not a speed claim


def test_live_page_shows_paused_then_follows_the_run_to_its_fault(
        h: Any, tmp_path: Path, sim_capture, request) -> None:
    out = tmp_path / "run"
    sim_capture.arm.append(lambda sim: (out / "PAUSE").touch())   # held before its first step
    codes: list[int] = []
    run = threading.Thread(target=lambda: codes.append(main([
        "run", str(h.write_procedure(tmp_path)), "--sim", "--out", str(out), "--seed", "5",
        "--inject", "table.interlock_open:always@T02.sf.+20dps"], on_sim_started=sim_capture)),
        daemon=True)
    run.start()
    request.addfinalizer(lambda: (out / "PAUSE").unlink(missing_ok=True))
    WebDriverWait(None, PATIENCE_S, poll_frequency=0.05).until(
        lambda _: (out / "journal.jsonl").exists() and b'"paused"' in
        (out / "journal.jsonl").read_bytes())

    server = WatchServer(out).start()
    browser = headless_chromium()
    try:
        browser.get(server.url)
        wait = WebDriverWait(browser, PATIENCE_S, poll_frequency=0.2)
        paused = browser.find_element(By.ID, "paused")
        wait.until(lambda b: paused.is_displayed())
        assert browser.find_element(By.ID, "state").text == "paused"
        assert browser.find_element(By.ID, "step").text == f"1/{len(h.SMALL_PLAN)}"
        assert browser.find_element(By.ID, "current").text == "T01.ramp"
        assert not browser.find_element(By.ID, "faultbox").is_displayed()
        # a dry run says so on the page (issue 28), from run_started's sim flag
        banner = browser.find_element(By.ID, "simulated")
        assert banner.is_displayed() and "SIMULATED run" in banner.text
        timeline = browser.find_elements(By.CSS_SELECTOR, "#timeline div")
        assert len(timeline) == len(h.SMALL_PLAN)
        assert "paused" in browser.find_element(By.ID, "events").text
        assert browser.find_element(By.ID, "eta").text != "--:--:--"

        (out / "PAUSE").unlink()                      # the operator lets it go on
        wait.until(lambda b: b.find_element(By.TAG_NAME, "body").get_attribute("data-state")
                   == "faulted")
        run.join(PATIENCE_S)
        assert codes == [EXIT_FAULT]
        assert not paused.is_displayed()
        faultbox = browser.find_element(By.ID, "faultbox")
        assert faultbox.is_displayed() and "T02.sf.+20dps" in faultbox.text
        assert "interlock" in faultbox.text.lower()
        fault_rows = browser.find_elements(By.CSS_SELECTOR, "#events tr.fault")
        assert fault_rows and any("fault" in row.text for row in fault_rows)
        # it followed the run: the step moved on and the signal is that of a logged step
        assert browser.find_element(By.ID, "step").text == f"8/{len(h.SMALL_PLAN)}"
        assert browser.find_element(By.ID, "sigstep").text.startswith("T0")
        done = browser.find_elements(By.CSS_SELECTOR, "#timeline div.done")
        assert len(done) == 7
        assert len(browser.find_elements(By.CSS_SELECTOR, "#signal canvas")) == 1
        if os.environ.get("GYROCAL_SCREENSHOTS"):    # how docs/watch-page.png is made
            browser.save_screenshot(str(Path(os.environ["GYROCAL_SCREENSHOTS"]) / "watch-page.png"))
    finally:
        browser.quit()
        server.stop()
