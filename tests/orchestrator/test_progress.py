import io

from gyrocal.orchestrator.progress import Progress


def test_the_live_line_shows_step_instruments_elapsed_and_eta():
    progress = Progress(enabled=False)
    progress.update(step_id="T03.sf.+100dps", step_index=40, step_count=139, chamber_c=-20.04,
                    table_dps=100.0, elapsed_s=3 * 3600 + 5, eta_s=16 * 3600 + 61)
    line = progress.line()
    assert "[40/139] T03.sf.+100dps" in line
    assert "-20.04 °C" in line and "100.00 °/s" in line
    assert "elapsed 03:00:05" in line and "ETA 16:01:01" in line


def test_quiet_when_stderr_is_not_a_terminal(monkeypatch, capsys):
    monkeypatch.setattr("sys.stderr", io.StringIO())
    progress = Progress()
    assert progress.enabled is False
    progress.update(step_id="T01.static", step_index=1, step_count=2)
    progress.close()
    assert capsys.readouterr().err == ""


def test_the_eta_counts_down_through_a_long_hold_and_never_below_the_later_steps():
    progress = Progress(enabled=False)
    progress.update(step_id="T02.soak", step_index=5, step_count=9, eta_s=3 * 3600,
                    step_expected_s=3600, step_started_s=100.0, elapsed_s=100.0)
    assert "ETA 03:00:00" in progress.line()
    progress.update(elapsed_s=100.0 + 1800)         # half-way through a one-hour soak
    assert "ETA 02:30:00" in progress.line()
    progress.update(elapsed_s=100.0 + 5400)         # the soak overran its plan by 30 min
    assert "ETA 02:00:00" in progress.line()        # the later steps' plan, not less


def test_the_live_line_says_paused_while_paused():
    progress = Progress(enabled=False)
    progress.update(step_id="T01.static", step_index=3, step_count=9, eta_s=600.0)
    assert "PAUSED" not in progress.line()
    progress.update(paused=True)
    assert progress.line().startswith("PAUSED") and "[3/9] T01.static" in progress.line()
    progress.update(paused=False)
    assert "PAUSED" not in progress.line()
