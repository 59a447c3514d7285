#!/usr/bin/env python3
"""Writes the mocked USB light sensors that tests/system/test_sensor_usb.c and
tests/system/test_sensor_hotplug.c run against: umockdev device descriptions
(*.umockdev) and usbmon captures (*.pcap) that umockdev replays.

Run it from anywhere; it rewrites the files beside it. The files are
committed, so the tests need nothing but umockdev at run time.

How umockdev replays a capture (umockdev 0.16 and later, "pcap" handler):
the capture is read in order; a submit ('S') record must match, in type,
endpoint, length and for OUT transfers the bytes, a transfer the program has
submitted; the matching complete ('C') record then hands the program its
status and IN data. So each capture below is the exact exchange skyd's
driver makes, in the order it makes it. Where a capture ends, the program's
next transfer never completes: the device has vanished mid-transfer, as far
as the program can tell. Timing is not replayed: a flood arrives as fast as
the program reaps it.

The drivers' side (daemon/sensor/sensor_hid.c, sensor_mcp2221.c) is
described in their headers; what each report means is said below where it
is written. The tests configure a report interval of TEST_INTERVAL_MS,
which the HID driver writes into the feature report.
"""
import os
import struct

HERE = os.path.dirname(os.path.abspath(__file__))
TEST_INTERVAL_MS = 50

# ---- usbmon captures (LINKTYPE_USB_LINUX_MMAPPED, 64-byte headers) ----

XFER_INTERRUPT, XFER_CONTROL = 1, 2


class Capture:
    """The records of one device's exchanges, written as classic pcap."""

    def __init__(self, bus, dev):
        self.bus, self.dev, self.records, self.next_id = bus, dev, [], 1

    def _record(self, urb_id, event, xfer, ep, setup, data, urb_len, status=0):
        hdr = struct.pack('<QBBBBHBBqiiII8siiII', urb_id, ord(event), xfer, ep, self.dev,
                          self.bus, 0 if setup is not None else ord('-'),
                          0 if data else ord('<' if ep & 0x80 else '>'),
                          0, len(self.records), status, urb_len, len(data),
                          setup if setup is not None else bytes(8), 0, 0, 0, 0)
        self.records.append(hdr + data)

    def control_in(self, request_type, request, value, index, length, answer, status=0):
        """A control transfer reading length bytes; the device answers, or
        refuses with status (-32, EPIPE: a stall)."""
        setup = struct.pack('<BBHHH', request_type, request, value, index, length)
        i = self._id()
        self._record(i, 'S', XFER_CONTROL, 0x80, setup, b'', length)
        self._record(i, 'C', XFER_CONTROL, 0x80, None, answer, len(answer), status)

    def control_out(self, request_type, request, value, index, data):
        """A control transfer writing data; the device takes it."""
        setup = struct.pack('<BBHHH', request_type, request, value, index, len(data))
        i = self._id()
        self._record(i, 'S', XFER_CONTROL, 0x00, setup, data, len(data))
        self._record(i, 'C', XFER_CONTROL, 0x00, None, b'', len(data))

    def interrupt_in(self, ep, size, answer):
        """An interrupt IN transfer of size bytes; the device sends answer."""
        i = self._id()
        self._record(i, 'S', XFER_INTERRUPT, ep, None, b'', size)
        self._record(i, 'C', XFER_INTERRUPT, ep, None, answer, len(answer))

    def interrupt_out(self, ep, data):
        i = self._id()
        self._record(i, 'S', XFER_INTERRUPT, ep, None, data, len(data))
        self._record(i, 'C', XFER_INTERRUPT, ep, None, b'', len(data))

    def _id(self):
        self.next_id += 1
        return 0xffff000000000000 | self.next_id

    def write(self, name):
        with open(os.path.join(HERE, name), 'wb') as f:
            f.write(struct.pack('<IHHiIII', 0xa1b2c3d4, 2, 4, 0, 0, 65535, 220))
            for n, r in enumerate(self.records):
                f.write(struct.pack('<IIII', n // 1000, n % 1000, len(r), len(r)))
                f.write(r)


# ---- device descriptions ----

def usb_descriptors(vid, pid, interfaces):
    """Device and configuration descriptors as sysfs' descriptors file
    holds them. interfaces: (class, extra class descriptor, endpoints)
    with endpoints (address, attributes, max packet, interval)."""
    body = b''
    for n, (cls, extra, eps) in enumerate(interfaces):
        body += bytes([9, 4, n, 0, len(eps), cls, 0, 0, 0]) + extra
        for addr, attr, size, interval in eps:
            body += struct.pack('<BBBBHB', 7, 5, addr, attr, size, interval)
    config = struct.pack('<BBHBBBBB', 9, 2, 9 + len(body), len(interfaces), 1, 0, 0x80, 50)
    device = struct.pack('<BBHBBBBHHHBBBB', 18, 1, 0x0200, 0, 0, 0, 64, vid, pid, 0x0100,
                         1, 2, 3, 1)
    return device + config + body


def hid_class_descriptor(report_len):
    return struct.pack('<BBHBBBH', 9, 0x21, 0x0111, 0, 1, 0x22, report_len)


def describe(port, dev, vid, pid, descriptors, product, serial, children=''):
    """One USB device at bus 1, port path 1-<port>, address dev."""
    return f"""P: /devices/pci0000:00/0000:00:14.0/usb1/1-{port}
N: bus/usb/001/{dev:03d}
E: DEVNAME=/dev/bus/usb/001/{dev:03d}
E: DEVTYPE=usb_device
E: DRIVER=usb
E: SUBSYSTEM=usb
E: BUSNUM=001
E: DEVNUM={dev:03d}
E: MAJOR=189
E: MINOR={dev - 1}
E: PRODUCT={vid:x}/{pid:x}/100
A: busnum=1
A: devnum={dev}
A: idVendor={vid:04x}
A: idProduct={pid:04x}
A: speed=12
A: bConfigurationValue=1
A: manufacturer=skyd tests
A: product={product}
A: serial={serial}
A: dev=189:{dev - 1}
H: descriptors={descriptors.hex().upper()}

{children}"""


def write_text(name, text):
    with open(os.path.join(HERE, name), 'w') as f:
        f.write(text)


# ---- a HID ambient light sensor (HID Sensor Usages, page 0x20) ----

def u16(x):
    return [x & 0xff, x >> 8]


def usage(x):
    return [0x0A] + u16(x)


def selectors(first, n):
    return sum((usage(first + k) for k in range(n)), [])


def als_report_descriptor(unit=(0xE1, 0x00, 0x00, 0x01)):
    """Report 1. Feature: Reporting State and Power State (named arrays,
    byte 1 and 2), Report Interval (ms, 32 bit, bytes 3-6), illuminance
    change sensitivity (16 bit, 0.01 lx, bytes 7-8). Input: Sensor State
    (named array, byte 1), Illuminance (32 bit, 0.01 lx a count, at most
    10^8 counts = 1 Mlx, bytes 2-5). unit: the illuminance's Unit item,
    lux (0x010000E1) unless told otherwise."""
    d = [0x05, 0x20, 0x09, 0x41, 0xA1, 0x01, 0x85, 0x01]
    d += usage(0x0316) + [0x15, 0, 0x25, 5, 0x75, 8, 0x95, 1, 0xA1, 0x02]
    d += selectors(0x0840, 6) + [0xB1, 0x00, 0xC0]
    d += usage(0x0319) + [0x15, 0, 0x25, 5, 0x75, 8, 0x95, 1, 0xA1, 0x02]
    d += selectors(0x0850, 6) + [0xB1, 0x00, 0xC0]
    d += usage(0x030E) + [0x15, 0, 0x27, 0xFF, 0xFF, 0xFF, 0x7F, 0x75, 32, 0x95, 1, 0x55, 0]
    d += [0xB1, 0x02]
    d += usage(0x14D1) + [0x15, 0, 0x26, 0xFF, 0xFF, 0x75, 16, 0x95, 1, 0x55, 0x0E, 0xB1, 0x02]
    d += usage(0x0201) + [0x15, 0, 0x25, 6, 0x75, 8, 0x95, 1, 0xA1, 0x02]
    d += selectors(0x0800, 7) + [0x81, 0x00, 0xC0]
    d += usage(0x04D1) + [0x15, 0, 0x27] + list(struct.pack('<I', 100000000))
    d += [0x75, 32, 0x95, 1, 0x67] + list(unit) + [0x55, 0x0E, 0x81, 0x02]
    d += [0xC0]
    return bytes(d)


READY, NOT_AVAILABLE = 1, 2		# Sensor State selectors 0x0801, 0x0802


def als_input(lux, state=READY):
    """Input report 1: sensor state, illuminance in 0.01 lx."""
    return struct.pack('<BBI', 1, state, round(lux * 100))


ALS_EP = 0x81
ALS_PACKET = 64


def als_device(port, dev, serial, desc, product='Test ambient light sensor'):
    return describe(port, dev, 0x1209, 0x0001, usb_descriptors(0x1209, 0x0001, [
        (3, hid_class_descriptor(len(desc)), [(ALS_EP, 3, ALS_PACKET, 10)])]),
        product, serial)


def als_setup(cap, desc):
    """What the HID driver does on opening: it reads the report
    descriptor, then feature report 1 (the device's settings: reporting
    no events, power undefined, 100 ms, sensitivity 1 lx), and writes it
    back with all events reported, full power (D0), the test's interval and
    no change threshold."""
    cap.control_in(0x81, 0x06, 0x2200, 0, len(desc), desc)	# GET_DESCRIPTOR report
    current = struct.pack('<BBBIH', 1, 0, 0, 100, 100)
    cap.control_in(0xA1, 0x01, 0x0301, 0, len(current), current)	# GET_REPORT feature 1
    wanted = struct.pack('<BBBIH', 1, 1, 1, TEST_INTERVAL_MS, 0)
    cap.control_out(0x21, 0x09, 0x0301, 0, wanted)		# SET_REPORT feature 1


# Illuminances the read scenario sends, in order.
ALS_READINGS = [1234.56, 1300.0, 25000.0, 0.5, 101325.0]


def als_read(bus, dev, name, readings=ALS_READINGS):
    """Set-up, then one input report per reading; then the capture ends
    with the next interrupt transfer pending: the device has vanished."""
    desc = als_report_descriptor()
    cap = Capture(bus, dev)
    als_setup(cap, desc)
    for lux in readings:
        cap.interrupt_in(ALS_EP, ALS_PACKET, als_input(lux))
    cap.write(name)


def als_garbage():
    """Good, then six kinds of garbage, then good again. The test expects
    2 accepted, 5 refused as malformed and 1 as not ready."""
    desc = als_report_descriptor()
    cap = Capture(1, 2)
    als_setup(cap, desc)
    cap.interrupt_in(ALS_EP, ALS_PACKET, als_input(500.0))
    cap.interrupt_in(ALS_EP, ALS_PACKET, bytes([7, 1, 0, 0, 0, 0]))	# unknown report id 7
    cap.interrupt_in(ALS_EP, ALS_PACKET, bytes([1, 1]))		# cut short
    cap.interrupt_in(ALS_EP, ALS_PACKET, b'')			# empty
    cap.interrupt_in(ALS_EP, ALS_PACKET, struct.pack('<BBI', 1, READY, 0xFFFFFFFF))	# > 10^8
    cap.interrupt_in(ALS_EP, ALS_PACKET, bytes([0xFF] * 3))	# noise: id 0xff
    cap.interrupt_in(ALS_EP, ALS_PACKET, als_input(700.0, NOT_AVAILABLE))	# sensor not ready
    cap.interrupt_in(ALS_EP, ALS_PACKET, als_input(800.0))
    cap.write('als-garbage.pcap')


FLOOD = 1000


def als_flood():
    """FLOOD input reports in a burst (replayed as fast as they are
    reaped, well above 1 kHz): noise of +-20 % around 400 lx."""
    desc = als_report_descriptor()
    cap = Capture(1, 2)
    als_setup(cap, desc)
    for k in range(FLOOD):
        cap.interrupt_in(ALS_EP, ALS_PACKET, als_input(480.0 if k % 2 else 320.0))
    cap.write('als-flood.pcap')


def als_kelvin():
    """A sensor whose illuminance field claims kelvin (0x00010001): every
    reading must be refused for its unit. It also stalls the request for
    its feature report, so skyd sets nothing and reads all the same."""
    desc = als_report_descriptor(unit=(0x01, 0x00, 0x01, 0x00))
    write_text('kelvin.umockdev', als_device(5, 6, 'KELVIN-1', desc, 'Sensor in kelvin'))
    cap = Capture(1, 6)
    cap.control_in(0x81, 0x06, 0x2200, 0, len(desc), desc)
    cap.control_in(0xA1, 0x01, 0x0301, 0, 9, b'', status=-32)	# GET_REPORT: stall
    for lux in (100.0, 200.0, 300.0):
        cap.interrupt_in(ALS_EP, ALS_PACKET, als_input(lux))
    cap.write('kelvin.pcap')


# ---- MCP2221A USB to I2C bridge with a BH1750 ----

MCP_IN, MCP_OUT = 0x83, 0x03


def mcp_device(port, dev, serial):
    """The MCP2221A as it enumerates: a CDC pair (interfaces 0 and 1) and
    the HID interface 2 with 64-byte interrupt endpoints 0x83 and 0x03."""
    hid_report = 28				# its vendor-defined report descriptor
    return describe(port, dev, 0x04D8, 0x00DD, usb_descriptors(0x04D8, 0x00DD, [
        (2, b'', [(0x82, 3, 8, 2)]),
        (10, b'', [(0x81, 2, 64, 0), (0x01, 2, 64, 0)]),
        (3, hid_class_descriptor(hid_report), [(MCP_IN, 3, 64, 1), (MCP_OUT, 3, 64, 1)])]),
        'MCP2221 USB-I2C/UART Combo', serial)


def report(*head):
    return bytes(head) + bytes(64 - len(head))


def status_answer(nack=False, engine=0):
    """0x10's answer: byte 1 0 (done), 3 0x20 (rate taken), 8 the I2C
    engine's state, 20 bit 6 an address NACK."""
    r = bytearray(report(0x10, 0x00, 0x00, 0x20, 117))
    r[8] = engine
    r[20] = 0x40 if nack else 0
    return bytes(r)


def mcp_exchange(cap, command, answer):
    """One command report OUT, its answer IN."""
    cap.interrupt_out(MCP_OUT, command)
    cap.interrupt_in(MCP_IN, 64, answer)


BH1750_COUNTS = [1000, 20000, 0xFFFF, 54000]	# the last but one saturates


def bh1750_lux(count):
    return count / 1.2 * 69 / 31


def mcp():
    """Set-up: I2C at 100 kHz (divider 12 MHz / 100 kHz - 3 = 117); the
    BH1750 is looked for at 0x23 (no answer: NACK, the transfer is
    cancelled) and found at 0x5c; measurement time 31, continuous high
    resolution. Then each poll: read 2 bytes (0x91), fetch them (0x40).
    Before the second reading one answer is garbage (it echoes 0x10 to a
    0x91); between the second and third one fetch fails (0x41). The
    capture ends after the last reading."""
    write_text('mcp.umockdev', mcp_device(3, 3, 'MCP-0001'))
    cap = Capture(1, 3)
    mcp_exchange(cap, report(0x10, 0, 0, 0x20, 117), status_answer())
    mcp_exchange(cap, report(0x90, 1, 0, 0x23 << 1, 0x01), report(0x90, 0x00))	# power on
    mcp_exchange(cap, report(0x10), status_answer(nack=True, engine=0x25))
    mcp_exchange(cap, report(0x10, 0, 0x10), report(0x10, 0x00, 0x10))		# cancel
    mcp_exchange(cap, report(0x90, 1, 0, 0x5c << 1, 0x01), report(0x90, 0x00))
    mcp_exchange(cap, report(0x10), status_answer())
    for byte in (0x40 | (31 >> 5), 0x60 | (31 & 0x1f), 0x10):
        mcp_exchange(cap, report(0x90, 1, 0, 0x5c << 1, byte), report(0x90, 0x00))
    for n, count in enumerate(BH1750_COUNTS):
        if n == 1:
            mcp_exchange(cap, report(0x91, 2, 0, 0x5c << 1 | 1), report(0x10, 0x00))	# garbage
        if n == 2:
            mcp_exchange(cap, report(0x91, 2, 0, 0x5c << 1 | 1), report(0x91, 0x00))
            mcp_exchange(cap, report(0x40), report(0x40, 0x41, 0x00, 127))	# failed
            mcp_exchange(cap, report(0x10, 0, 0x10), report(0x10, 0x00, 0x10))	# cancel
        mcp_exchange(cap, report(0x91, 2, 0, 0x5c << 1 | 1), report(0x91, 0x00))
        mcp_exchange(cap, report(0x40), report(0x40, 0x00, 0x55, 2, count >> 8, count & 0xff))
    cap.write('mcp.pcap')


# ---- a keyboard, which must never be opened ----

KEYBOARD_REPORT = bytes([
    0x05, 0x01, 0x09, 0x06, 0xA1, 0x01, 0x05, 0x07, 0x19, 0xE0, 0x29, 0xE7, 0x15, 0x00,
    0x25, 0x01, 0x75, 0x01, 0x95, 0x08, 0x81, 0x02, 0x95, 0x01, 0x75, 0x08, 0x81, 0x01,
    0x95, 0x06, 0x75, 0x08, 0x15, 0x00, 0x25, 0x65, 0x05, 0x07, 0x19, 0x00, 0x29, 0x65,
    0x81, 0x00, 0xC0])


def keyboard():
    """A HID keyboard bound to usbhid: its interface and HID device are in
    sysfs with the report descriptor the kernel read. skyd reads that and
    leaves the keyboard alone."""
    base = '/devices/pci0000:00/0000:00:14.0/usb1/1-4'
    children = f"""P: {base}/1-4:1.0
E: DEVTYPE=usb_interface
E: DRIVER=usbhid
E: SUBSYSTEM=usb
A: bInterfaceClass=03
A: bInterfaceNumber=00

P: {base}/1-4:1.0/0003:1209:0003.0001
E: DRIVER=hid-generic
E: SUBSYSTEM=hid
H: report_descriptor={KEYBOARD_REPORT.hex().upper()}

"""
    write_text('keyboard.umockdev', describe(4, 4, 0x1209, 0x0003, usb_descriptors(
        0x1209, 0x0003, [(3, hid_class_descriptor(len(KEYBOARD_REPORT)), [(0x81, 3, 8, 10)])]),
        'Test keyboard', 'KBD-1', children))


def main():
    desc = als_report_descriptor()
    write_text('als.umockdev', als_device(2, 2, 'ALS-0001', desc))
    als_read(1, 2, 'als.pcap')
    als_garbage()
    als_flood()
    als_kelvin()
    mcp()
    keyboard()
    # Unplugged and plugged back in: same port, the next address.
    write_text('als-replug.umockdev', als_device(2, 5, 'ALS-0001', desc))
    als_read(1, 5, 'als-replug.pcap', readings=[4321.0, 4400.0])


if __name__ == '__main__':
    main()
