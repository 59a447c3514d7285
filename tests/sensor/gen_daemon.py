#!/usr/bin/env python3
"""Writes the usbmon captures that the daemon's sensor test
(tests/system/test_daemon_sensor.c) and latbench's sensor figure replay: the same
devices as gen.py's (als.umockdev, mcp.umockdev), other exchanges. gen.py
says how umockdev replays a capture; its helpers write these too.

Run it from anywhere; it rewrites its files beside it. They are committed.
"""
from gen import (ALS_EP, ALS_PACKET, NOT_AVAILABLE, Capture, als_input, als_report_descriptor,
                 als_setup, mcp_exchange, report, status_answer)

BH1750_AT = 0x23


def mcp_setup(cap):
    """The MCP2221A at 100 kHz with the BH1750 answering at 0x23 (no NACK):
    measurement time 31, continuous high resolution."""
    mcp_exchange(cap, report(0x10, 0, 0, 0x20, 117), status_answer())
    mcp_exchange(cap, report(0x90, 1, 0, BH1750_AT << 1, 0x01), report(0x90, 0x00))
    mcp_exchange(cap, report(0x10), status_answer())
    for byte in (0x40 | (31 >> 5), 0x60 | (31 & 0x1f), 0x10):
        mcp_exchange(cap, report(0x90, 1, 0, BH1750_AT << 1, byte), report(0x90, 0x00))


def mcp_polls(name, counts):
    """Set-up, then one poll per count (read two bytes, fetch them); skyd
    polls every report_interval_s (at least 81 ms), so the readings come
    paced, unlike an HID device's, which replay as fast as they are reaped.
    The capture ends after the last: the device then stops answering."""
    cap = Capture(1, 3)
    mcp_setup(cap)
    for count in counts:
        mcp_exchange(cap, report(0x91, 2, 0, BH1750_AT << 1 | 1), report(0x91, 0x00))
        mcp_exchange(cap, report(0x40), report(0x40, 0x00, 0x55, 2, count >> 8, count & 0xff))
    cap.write(name)


# The cloud scenario's readings, in counts of 1.855 lx: 10, 25, 40, 55 klx
# nearly; the test reads the lux back as bh1750_lux(count).
CLOUD_COUNTS = [5391, 13478, 21565, 29652]

# latbench: a ramp of distinct readings, each a change of the sky.
RAMP_POLLS = 200


def ramp_counts():
    return [10000 + 37 * k for k in range(RAMP_POLLS)]


def als_readings(name, readings):
    """The HID sensor's set-up, one input report per reading, then the end
    of the capture (the device vanishes with a transfer pending)."""
    desc = als_report_descriptor()
    cap = Capture(1, 2)
    als_setup(cap, desc)
    for lux in readings:
        cap.interrupt_in(ALS_EP, ALS_PACKET, als_input(lux))
    cap.write(name)


def als_junk():
    """One good reading (20 klx), then six that must be refused and leave
    the sky alone: an unknown report id, a short report, an empty one,
    300 klx (above sensor_max_lux), a sensor not ready, noise. Then the
    capture ends. Expected: 1 accepted; malformed 4, high 1, not_ready 1."""
    desc = als_report_descriptor()
    cap = Capture(1, 2)
    als_setup(cap, desc)
    cap.interrupt_in(ALS_EP, ALS_PACKET, als_input(20000.0))
    cap.interrupt_in(ALS_EP, ALS_PACKET, bytes([7, 1, 0, 0, 0, 0]))
    cap.interrupt_in(ALS_EP, ALS_PACKET, bytes([1, 1]))
    cap.interrupt_in(ALS_EP, ALS_PACKET, b'')
    cap.interrupt_in(ALS_EP, ALS_PACKET, als_input(300000.0))
    cap.interrupt_in(ALS_EP, ALS_PACKET, als_input(700.0, NOT_AVAILABLE))
    cap.interrupt_in(ALS_EP, ALS_PACKET, bytes([0xFF] * 3))
    cap.write('als-junk.pcap')


def main():
    mcp_polls('mcp-cloud.pcap', CLOUD_COUNTS)
    mcp_polls('mcp-ramp.pcap', ramp_counts())
    als_junk()
    # Elevation: civil twilight's end (reported, applied), no light at all
    # (outside the curve: reported, not applied), then a bright morning.
    als_readings('als-elevation.pcap', [3.0, 0.0, 25000.0])


if __name__ == '__main__':
    main()
