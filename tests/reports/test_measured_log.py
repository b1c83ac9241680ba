import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from gyrocal.analysis.measured_log import LogFormatError, read_measured_log

HEADER = "t_s,table_rate_dps,chamber_temp_c,gyro,sensor_temp_c\n"


def write(tmp_path, body, header=HEADER, name="log.csv"):
    path = tmp_path / name
    path.write_text(header + body)
    return path


def test_a_good_csv_is_read_with_its_sample_rate(tmp_path):
    rows = "".join(f"{i * 0.01},{10.0},{25.0},{10.001},{25.5}\n" for i in range(100))
    log = read_measured_log(write(tmp_path, rows))
    assert len(log) == 100
    assert log.sample_rate_hz == pytest.approx(100.0)
    assert log.sensor_temp_c is not None and log.table_angle_deg is None


@pytest.mark.parametrize(
    "body, header, message",
    [
        ("0,1,25,1\n0.1,1,25,1\n", "t_s,table_rate_dps,chamber_temp_c,gyro\n", None),
        ("0,1,25\n", "t_s,table_rate_dps,chamber_temp_c\n", r"missing required column\(s\) gyro"),
        ("0,1,25,1,25\n0.1,1,nan,1,25\n", HEADER, r"line 3: column chamber_temp_c: non-finite"),
        ("0,1,25,1,25\n0.1,1,25,1,25\n0.1,1,25,1,25\n", HEADER, r"line 4: column t_s: time 0.1 does not increase"),
        ("0,1,25,1,25\n0.1,1,x,1,25\n", HEADER, r"line 3: column chamber_temp_c: 'x' is not a number"),
        ("0,1,25,1,25\n0.1,1,25\n", HEADER, r"line 3: 3 fields, the header has 5"),
    ],
)
def test_bad_rows_are_errors_that_name_line_and_column(tmp_path, body, header, message):
    path = write(tmp_path, body, header)
    if message is None:
        assert len(read_measured_log(path)) == 2
        return
    with pytest.raises(LogFormatError, match=message):
        read_measured_log(path)


def test_parquet_logs_are_checked_the_same_way(tmp_path):
    t = np.arange(10) * 0.1
    gyro = np.ones(10)
    gyro[4] = np.inf
    table = pa.table({"t_s": t, "table_rate_dps": t, "chamber_temp_c": t, "gyro": gyro})
    path = tmp_path / "log.parquet"
    pq.write_table(table, path)
    with pytest.raises(LogFormatError, match=r"log.parquet: line 5: column gyro: non-finite"):
        read_measured_log(path)
