"""The live page in a real headless Chromium, watching a real simulated run advance and fault.

The run goes through ``gyrocal run --sim`` in this process (a thread); it is
held paused before its first step by the operator's PAUSE file, so the page
can be seen PAUSED, then let go; an injected interlock opening at
T02.sf.+20dps faults it. The page reads only the run folder. Chromium and
chromedriver come from Debian (``make browser``); missing, this test FAILS:
a browser test that skips is a check not made.
"""

from __future__ import annotations

import json
import os
import re
import threading
from pathlib import Path
from typing import Any

from selenium.webdriver.common.by import By
from selenium.webdriver.support.ui import WebDriverWait

from gyrocal.app.watch.server import WatchServer
from gyrocal.cli import EXIT_FAULT, main
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
        events = browser.find_element(By.ID, "events").text
        assert "paused" in events
        # the journal as readable lines: units from the key names, no hashes, no raw dicts
        assert re.search(r"chamber -?\d+(\.\d+)? °C", events), events
        assert re.search(r"table rate -?[\d.e-]+ deg/s", events), events
        assert not re.search(r"[0-9a-f]{64}", events)
        assert "{" not in events and "prev_sha256" not in events
        # a dry run on simulated time has no clock-time end; the page says why
        assert browser.find_element(By.ID, "ends").text == \
            "expected end as fast as the machine allows (simulated time)"
        assert not browser.find_element(By.ID, "verdictbox").is_displayed()
        # time remaining is a labelled duration, not something that reads as a clock time
        remaining = browser.find_element(By.ID, "remaining").text
        assert remaining.startswith("remaining (procedure time) "), remaining
        assert re.fullmatch(r"(\d+ h \d\d min \d\d s|\d+ min \d\d s|\d+ s)",
                            browser.find_element(By.ID, "eta").text)

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
        events = browser.find_element(By.ID, "events").text
        assert re.search(r"\d+ samples written \(attempt1-chunk\d+\.parquet\)", events), events
        assert not re.search(r"[0-9a-f]{64}", events)
        # nothing is logged during spin-ups, ramps and soaks: the table-rate plot has a gap
        # (a null) between logged steps, never a line drawn across them
        t_s, rate = browser.execute_script("return [plots.table.data[0], plots.table.data[1]];")
        gaps = [i for i, v in enumerate(rate) if v is None]
        assert gaps and all(0 < i < len(rate) - 1 for i in gaps)
        assert all(rate[i - 1] is not None and rate[i + 1] is not None for i in gaps)
        assert all(t_s[i + 1] - t_s[i - 1] > 1.0 for i in gaps)
        if os.environ.get("GYROCAL_SCREENSHOTS"):    # how docs/watch-page.png is made
            browser.save_screenshot(str(Path(os.environ["GYROCAL_SCREENSHOTS"]) / "watch-page.png"))
    finally:
        browser.quit()
        server.stop()


def test_a_finished_run_shows_its_verdict_and_links_its_report(h: Any, tmp_path: Path) -> None:
    """"done" is not enough: the page shows the verdict the report reached, why, and a link
    that opens the report itself (served read-only from the run folder)."""
    out = tmp_path / "run"
    code = main(["run", str(h.write_procedure(tmp_path)), "--sim", "--out", str(out),
                 "--seed", "5"])
    results = json.loads((out / "report" / "results.json").read_text())
    verdict = results["verdict"]["overall"]
    assert code == (0 if verdict == "PASS" else 1)
    server = WatchServer(out).start()
    browser = headless_chromium()
    try:
        browser.get(server.url)
        wait = WebDriverWait(browser, PATIENCE_S, poll_frequency=0.2)
        box = browser.find_element(By.ID, "verdictbox")
        wait.until(lambda b: box.is_displayed())
        assert browser.find_element(By.ID, "state").text == "done"
        assert browser.find_element(By.ID, "verdict").text == verdict
        assert verdict in box.get_attribute("class").split()
        assert browser.find_element(By.ID, "eta").text == "0 s"
        assert browser.find_element(By.ID, "end").text == "– (the run has ended)"
        failed = [a["name"] for a in results["acceptance"] if a["pass"] is False]
        detail = browser.find_element(By.ID, "verdict_detail").text
        assert all(name in detail for name in failed)
        link = browser.find_element(By.ID, "report_link")
        assert link.text == "open the report" and link.is_displayed()
        if os.environ.get("GYROCAL_SCREENSHOTS"):
            browser.save_screenshot(str(Path(os.environ["GYROCAL_SCREENSHOTS"])
                                        / "watch-page-done.png"))
        link.click()
        wait.until(lambda b: b.current_url.endswith("/report/report.html"))
        assert "Engine fault test" in browser.page_source
        assert verdict in browser.find_element(By.TAG_NAME, "body").text
    finally:
        browser.quit()
        server.stop()
