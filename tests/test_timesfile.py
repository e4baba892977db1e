"""Times files as people and spreadsheets write them: decimal commas, semicolons, and every
number checked; a time is never silently cut to whole seconds."""

from __future__ import annotations

import os

import pytest

from station.errors import InputError
from station.timing.timesfile import read_times

ORDER = ["PC1", "PC2", "PC3"]


def _read(tmp_path, text: str, name: str = "t.csv"):
    path = tmp_path / name
    path.write_bytes(text.encode("utf-8"))
    return read_times(str(path), ORDER)


@pytest.mark.parametrize(
    "text",
    [
        "photocell,time\nPC1,10:41:07.2345\nPC2,10:41:11.5\nPC3,10:41:14.125\n",
        'photocell,time\nPC1,"10:41:07,2345"\nPC2,"10:41:11,5"\nPC3,"10:41:14,125"\n',
        "photocell,time\nPC1,10:41:07,2345\nPC2,10:41:11,5\nPC3,10:41:14,125\n",
        "photocell;time\nPC1;10:41:07,2345\nPC2;10:41:11,5\nPC3;10:41:14,125\n",
        "\ufeffPhotocell;Time;;\r\nPC1;10:41:07,2345;;\r\nPC2;10:41:11,5;;\r\nPC3;10:41:14,125;;\r\n",
        "photocell\ttime\nPC1\t10:41:07,2345\nPC2\t10:41:11.5\nPC3\t10:41:14,125\n",
    ],
    ids=["point", "quoted-comma", "unquoted-comma", "semicolon", "excel-semicolon", "tab"],
)
def test_decimal_commas_and_spreadsheet_csv_give_the_same_times(tmp_path, text):
    d = _read(tmp_path, text)
    t0 = 10 * 3600 + 41 * 60
    assert d.times == pytest.approx([t0 + 7.2345, t0 + 11.5, t0 + 14.125], abs=1e-9)
    assert d.photocells == ORDER


def test_seconds_with_a_decimal_comma(tmp_path):
    d = _read(tmp_path, "photocell;time\nPC1;0\nPC2;4,5\nPC3;12,345\n")
    assert d.times == pytest.approx([0.0, 4.5, 12.345])


@pytest.mark.parametrize(
    ("text", "expect"),
    [
        ("photocell,time\nPC1,0\nPC2,nan\nPC3,9\n", ":3: field time: 'nan' is not a number"),
        ("photocell,time\nPC1,0\nPC2,inf\nPC3,9\n", ":3: field time: 'inf' is not a number"),
        ("photocell,time\nPC1,0\nPC2,1e400\nPC3,9\n", ":3: field time: '1e400' is not a number"),
        ("photocell,time\nPC1,0\nPC2,1e300\nPC3,9\n", "'1e300' s is not a time a timer gives"),
        ("photocell,time\nPC1,0\nPC2,1,234.5\nPC3,9\n", ":3: expected 2 columns, found 3"),
        ("photocell,time\nPC1,0\nPC2,4.5,7\nPC3,9\n", "(a decimal comma in a comma-separated"),
        ("photocell,time\nPC1,0\nPC2,٣\nPC3,9\n", ":3: field time: '٣' is not a number"),
        ("photocell,time\nPC1,0\nPC2,4²\nPC3,9\n", ":3: field time: '4²' is not a number"),
        ("photocell,time\nPC1,10:00:00\nPC2,10:²0:04\nPC3,10:00:09\n", "is not hh:mm:ss"),
        ("photocell,time\nPC1,10:00:00\nPC2,10:00:60,5\nPC3,10:00:09\n", "not a valid time of"),
        ("photocell,time\nPC1,0\nPC2,4\nPC3,4000\n", ":4: field time: the times span 4000 s"),
        ("photocell,time\nPC1,0\nPC2,\x00\nPC3,9\n", "t.csv:3"),
        ("photocell;time\nPC1;0\nPC2;4;5;6\nPC3;9\n", ":3: expected 2 columns, found 4"),
        ("photocell,time\nPC1,0\nPC2\nPC3,9\n", ":3: expected 2 columns, found 1"),
        ("photocell,time\nPC1,0\nPC2,4\n\xff", "not a UTF-8 text times file"),
    ],
)
def test_every_number_is_checked_with_file_line_and_field(tmp_path, text, expect):
    path = tmp_path / "t.csv"
    path.write_bytes(text.encode("utf-8").replace("\xff".encode(), b"\xff"))
    with pytest.raises(InputError) as err:
        read_times(str(path), ORDER)
    assert expect in str(err.value)
    assert "\n" not in str(err.value)


@pytest.mark.parametrize("special", ["/dev/zero", "fifo", "folder", "missing", "huge"])
def test_special_files_are_refused_not_read(tmp_path, special):
    if special == "fifo":
        path = str(tmp_path / "fifo.csv")
        os.mkfifo(path)  # opening it for reading would block forever
        expect = "is a pipe (FIFO), not a times file"
    elif special == "folder":
        path, expect = str(tmp_path), "is a folder, not a times file"
    elif special == "missing":
        path, expect = str(tmp_path / "nope.csv"), "cannot read times file: no such file"
    elif special == "huge":
        path = str(tmp_path / "huge.csv")
        with open(path, "wb") as fh:
            fh.truncate(5 * 1024 * 1024)  # sparse: 5 MB of NUL bytes
        expect = "is 5.0 MB; a times file is at most 4.0 MB"
    else:
        path, expect = special, "is a character device, not a times file"
    with pytest.raises(InputError) as err:
        read_times(path, ORDER)
    assert expect in str(err.value)
