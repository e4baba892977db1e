"""Finding the timer: ``station ports`` and the check of the configured port."""

from __future__ import annotations

import json
import os

import pytest

from station.errors import InputError
from station.session.ports import SerialPortInfo, check_port, list_serial_ports
from tests.timing_helpers import write_config

FTDI = SerialPortInfo(
    "/dev/ttyUSB3", "FT232R USB UART", "USB VID:PID=0403:6001 SER=A50285BI", "FTDI"
)
ONBOARD = SerialPortInfo("/dev/ttyS0", "n/a", "n/a")


def test_a_port_that_does_not_exist_is_named_with_the_ports_there_are(tmp_path):
    with pytest.raises(InputError) as exc:
        check_port("/dev/ttyUSB0", "station.yaml", ports=[FTDI, ONBOARD])
    text = str(exc.value)
    assert text.startswith("station.yaml: field serial.port: serial port /dev/ttyUSB0 does not")
    assert "/dev/ttyUSB3 (FT232R USB UART), /dev/ttyS0" in text and "\n" not in text
    with pytest.raises(InputError, match="no serial port found: is the USB-serial adapter"):
        check_port(str(tmp_path / "ttyUSB0"), ports=[])


def test_a_pseudo_terminal_and_pyserial_urls_pass():
    master, slave = os.openpty()
    try:
        check_port(os.ttyname(slave), ports=[])
    finally:
        os.close(master)
        os.close(slave)
    for url in ("socket://localhost:7000", "loop://", "rfc2217://host:2217"):
        check_port(url, ports=[])


@pytest.mark.skipif(os.geteuid() == 0, reason="root opens any device")
def test_no_permission_names_the_dialout_group(tmp_path):
    dev = tmp_path / "ttyUSB0"
    dev.write_text("")
    dev.chmod(0)
    with pytest.raises(InputError, match="dialout group"):
        check_port(str(dev), ports=[])


def test_usb_adapters_are_listed_first(monkeypatch):
    from serial.tools import list_ports
    from serial.tools.list_ports_common import ListPortInfo

    def fake(include_links=False):
        a = ListPortInfo("/dev/ttyS0", skip_link_detection=True)
        b = ListPortInfo("/dev/ttyUSB0", skip_link_detection=True)
        b.vid, b.pid, b.serial_number, b.product = 0x0403, 0x6001, "A5", "FT232R USB UART"
        b.manufacturer = "FTDI"
        b.apply_usb_info()  # as the Linux lister does: hwid "USB VID:PID=…"
        return [a, b]

    monkeypatch.setattr(list_ports, "comports", fake)
    ports = list_serial_ports()
    assert [p.device for p in ports] == ["/dev/ttyUSB0", "/dev/ttyS0"]
    assert ports[0].is_usb and "0403:6001" in ports[0].hwid
    assert ports[0].line().startswith("/dev/ttyUSB0  FT232R USB UART  (FTDI; USB VID:PID")


def test_station_ports_and_record_on_a_missing_port(run_station, tmp_path):
    r = run_station("ports", "--json")
    assert r.returncode == 0, r.stderr
    listed = json.loads(r.stdout)
    assert all({"device", "description", "hwid", "accessible"} <= set(p) for p in listed)
    assert run_station("ports").returncode == 0
    cfg = write_config(tmp_path, str(tmp_path / "ttyUSB9"))
    for cmd in ("record", "live"):
        r = run_station(cmd, "--config", cfg, "--session-dir", tmp_path / "s")
        assert r.returncode == 2
        lines = r.stderr.strip().splitlines()
        assert len(lines) == 1 and "ttyUSB9 does not exist" in lines[0], r.stderr
        assert "station ports" in lines[0]
        assert not (tmp_path / "s").exists()
