import pytest

from gyrocal.instruments.errors import InstrumentProtocolError, InstrumentTimeout
from gyrocal.instruments.retry import RetryPolicy, call_with_retry


def test_transient_errors_are_retried_with_growing_backoff_and_reported():
    calls, sleeps, reported = [], [], []

    def flaky():
        calls.append(1)
        if len(calls) < 3:
            raise InstrumentTimeout("chamber", "read PV")
        return 42

    result = call_with_retry(
        flaky, RetryPolicy(attempts=3, backoff_s=0.1), on_retry=lambda n, e: reported.append(n),
        sleep=sleeps.append,
    )
    assert result == 42
    assert sleeps == [0.1, 0.2]
    assert reported == [1, 2]


def test_retries_are_bounded_and_the_last_error_propagates():
    def dead():
        raise InstrumentTimeout("table", ":read:rate? 1")

    with pytest.raises(InstrumentTimeout, match="table: :read:rate\\? 1: no reply"):
        call_with_retry(dead, RetryPolicy(attempts=2, backoff_s=0), sleep=lambda s: None)


def test_non_transient_errors_are_not_retried():
    calls = []

    def refused():
        calls.append(1)
        raise InstrumentProtocolError("chamber", "write SP", "Modbus exception 2", reply=b"\x01\x86\x02")

    with pytest.raises(InstrumentProtocolError):
        call_with_retry(refused, RetryPolicy(attempts=5, backoff_s=0), sleep=lambda s: None)
    assert calls == [1]
