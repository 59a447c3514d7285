#!/usr/bin/python3
"""soak.py - skyd under seeded random load for a long time, with its
resources sampled once a minute: resident memory, file descriptors,
threads and shared-memory regions (memfds mapped or held), of a controller
and of its follower (docs/performance.md, "Soak").

The controller runs under umockdev-run with a replayed HID light sensor
(tests/sensor: als.umockdev, als-flood.pcap; once the capture ends the
device stops answering and is looked for, opened and failed again for the
rest of the run) and replicates to the follower through a mosquitto of
its own on a free loopback port. Clients of both connect and leave,
subscribe (the regions they receive mapped and let go), change the sky
(sets, batches, sizes and storage that replace the region, the clock, the
weather, the sensor's mode), add and drop views, sample and read; one step
every 0 to 200 ms, the choices from the seed.

    tools/soak.py [--minutes 60] [--seed 1] [--build build] [--out FILE]

Prints a line per sample and, at the end, each figure's first, last, least
and greatest value and its growth per hour (a least-squares line through
the samples after the first ten minutes). Needs mosquitto; without
umockdev-run the controller runs without the sensor. Not a test: nothing
here passes or fails."""

import argparse
import array
import mmap
import os
import random
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
SYSFS = '/sys/devices/pci0000:00/0000:00:14.0/usb1/1-'
SMALL = ['transmittance_width=64', 'transmittance_height=16', 'transmittance_steps=16',
         'multiscatter_width=8', 'multiscatter_height=8', 'multiscatter_steps=8',
         'multiscatter_dirs=2', 'skyview_width=32', 'skyview_height=16', 'skyview_steps=8',
         'aerial_width=8', 'aerial_height=8', 'aerial_depth=4']
# Keys and the values drawn for them: all valid, so that every change is one.
NUMBERS = {
    'sun_elevation_deg': (-10, 90), 'sun_azimuth_deg': (0, 360), 'ground_albedo': (0, 1),
    'mie_g': (0.5, 0.9), 'camera_yaw_deg': (0, 360), 'camera_pitch_deg': (-30, 60),
    'altitude_km': (0, 5), 'lat_deg': (-60, 60), 'lon_deg': (-180, 180),
    'time_rate': (0, 600), 'moon_elevation_deg': (-20, 60),
}
CHOICES = {
    'visibility_km': ['auto', '5', '20', '80'], 'cloud_oktas': ['auto', '0', '4', '8'],
    'aerosol': ['auto', 'urban', 'maritime'], 'sun_mode': ['manual', 'clock'],
    'moon_mode': ['manual', 'clock'], 'sensor_mode': ['off', 'cloud', 'exposure'],
    'skyview_width': ['24', '32', '48'], 'aerial_depth': ['4', '6'], 'storage': ['f32', 'f16'],
    'metar': ['"EGLL 241250Z 24012KT 9999 FEW030 SCT250 18/09 Q1021"',
              '"LFPG 091030Z VRB02KT 0300 FG VV001 08/08 Q1030"'],
}


def free_port():
    with socket.socket() as s:
        s.bind(('127.0.0.1', 0))
        return s.getsockname()[1]


def wait_for(pred, seconds, what):
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        if pred():
            return
        time.sleep(0.05)
    sys.exit('soak: %s did not come' % what)


class Client:
    """A connection speaking the protocol; the fds that come along are
    mapped (read as a client reads a region) and closed."""

    def __init__(self, path):
        self.s = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        self.s.settimeout(60)
        self.s.connect(path)
        self.buf = b''
        self.subscribed = False
        self.line()

    def _read(self, block):
        self.s.setblocking(block)
        if block:
            self.s.settimeout(60)
        try:
            data, anc, _, _ = self.s.recvmsg(65536, socket.CMSG_SPACE(16))
        except (BlockingIOError, InterruptedError):
            return False
        for level, kind, raw in anc:
            if level == socket.SOL_SOCKET and kind == socket.SCM_RIGHTS:
                fds = array.array('i')
                fds.frombytes(raw[:len(raw) - len(raw) % 4])
                for fd in fds:
                    size = os.fstat(fd).st_size
                    if size:
                        with mmap.mmap(fd, size, mmap.MAP_SHARED, mmap.PROT_READ) as m:
                            m[:64]
                    os.close(fd)
        if not data:
            raise ConnectionError('closed')
        self.buf += data
        return True

    def line(self):
        while b'\n' not in self.buf:
            self._read(True)
        line, self.buf = self.buf.split(b'\n', 1)
        return line.decode(errors='replace')

    def request(self, text):
        self.s.setblocking(True)
        self.s.settimeout(60)
        self.s.sendall(text.encode() + b'\n')
        while True:
            line = self.line()
            if line == 'OK' or line.startswith('ACK ['):
                return line

    def drain(self):
        try:
            while self._read(False):
                pass
        except ConnectionError:
            return False
        lines = self.buf.split(b'\n')
        tail = lines.pop()
        self.buf = b''.join(l + b'\n' for l in lines
                            if not l.startswith((b'changed:', b'layout:', b'sensor:'))) + tail
        return True

    def close(self):
        self.s.close()


class Skyd:
    def __init__(self, build, tmp, name, args, wrap=()):
        self.sock = os.path.join(tmp, name + '.sock')
        self.log = open(os.path.join(tmp, name + '.log'), 'w')
        cmd = list(wrap) + [os.path.join(build, 'daemon', 'skyd'), '--socket', self.sock] + args
        self.proc = subprocess.Popen(cmd, stderr=self.log, stdout=self.log)
        wait_for(lambda: os.path.exists(self.sock), 120, name + "'s socket")
        self.pid = self._skyd_pid(bool(wrap))

    def _skyd_pid(self, wrapped):
        if not wrapped:
            return self.proc.pid
        path = '/proc/%d/task/%d/children' % (self.proc.pid, self.proc.pid)
        wait_for(lambda: open(path).read().split(), 30, 'skyd under umockdev-run')
        return int(open(path).read().split()[0])

    def stop(self):
        self.proc.send_signal(signal.SIGTERM)
        self.proc.wait(60)


def sample(pid):
    """RSS (KiB), fds, threads and the shared-memory regions it holds:
    distinct memfds among its mappings and its fds."""
    status = dict(l.split(':', 1) for l in open('/proc/%d/status' % pid) if ':' in l)
    fds = os.listdir('/proc/%d/fd' % pid)
    regions = set()
    for fd in fds:
        try:
            target = os.readlink('/proc/%d/fd/%s' % (pid, fd))
        except OSError:
            continue
        if target.startswith('/memfd:'):
            regions.add(os.stat('/proc/%d/fd/%s' % (pid, fd)).st_ino)
    for line in open('/proc/%d/maps' % pid):
        parts = line.split()
        if len(parts) >= 6 and parts[5].startswith('/memfd:'):
            regions.add(int(parts[4]))
    return (int(status['VmRSS'].split()[0]), len(fds), int(status['Threads']), len(regions))


def step(rng, clients, socks):
    """One action of the load on a client of the controller or the follower;
    a client whose connection failed is dropped and said."""
    if len(clients) < 4 or (len(clients) < 12 and rng.random() < 0.1):
        path = rng.choice(socks)
        clients.append((path, Client(path)))
        return
    path, c = rng.choice(clients)
    a = rng.random()
    if a < 0.08:
        clients.remove((path, c))
        c.close()
        return
    try:
        act(rng, c, a, path == socks[0])
    except (ConnectionError, OSError) as e:
        print('soak: a client of %s lost its connection: %s' % (path, e), file=sys.stderr)
        clients.remove((path, c))
        c.close()


def act(rng, c, a, controller):
    if a < 0.20 and not c.subscribed:
        c.request('subscribe tables=%s events=1' % rng.choice(['all', 'skyview', 'aerial,skyview']))
        c.subscribed = True
    elif a < 0.55 and controller:
        key = rng.choice(list(NUMBERS) + list(CHOICES))
        value = (rng.choice(CHOICES[key]) if key in CHOICES
                 else '%.4f' % rng.uniform(*NUMBERS[key]))
        c.request('set %s=%s' % (key, value))
    elif a < 0.62 and controller:
        c.s.sendall(b'batch\n')
        for key in rng.sample(sorted(NUMBERS), 3):
            c.s.sendall(('set %s=%.4f\n' % (key, rng.uniform(*NUMBERS[key]))).encode())
        c.request('end')
    elif a < 0.72 and controller:
        name = 'soak%d' % rng.randrange(4)
        if rng.random() < 0.6:
            c.request('view add name=%s yaw_deg=%.1f form=%s' % (
                name, rng.uniform(0, 360), rng.choice(['volume', 'panorama'])))
        else:
            c.request('view del name=%s' % name)
    elif a < 0.85:
        c.request(rng.choice(['sample sun', 'sample ambient', 'sample sky el_deg=20 az_deg=90']))
    else:
        c.request(rng.choice(['status', 'get', 'get sun', 'get weather', 'get sensor', 'view list']))


def slope_per_hour(points):
    """Least-squares slope of (minutes, value) points, per hour."""
    n = len(points)
    if n < 2:
        return 0.0
    mx = sum(p[0] for p in points) / n
    my = sum(p[1] for p in points) / n
    sxx = sum((p[0] - mx) ** 2 for p in points)
    return 60.0 * sum((p[0] - mx) * (p[1] - my) for p in points) / sxx if sxx else 0.0


def summary(samples, names, out):
    figures = ('rss_kib', 'fds', 'threads', 'regions')
    for who in names:
        rows = [(t, s) for t, w, s in samples if w == who]
        print('%s:' % who, file=out)
        for i, fig in enumerate(figures):
            values = [s[i] for _, s in rows]
            late = [(t, s[i]) for t, s in rows if t >= 10]
            print('  %-8s first %8d  last %8d  min %8d  max %8d  growth after 10 min %+.1f/h'
                  % (fig, values[0], values[-1], min(values), max(values), slope_per_hour(late)),
                  file=out)


def start_rig(args, tmp):
    port = free_port()
    conf = os.path.join(tmp, 'mosquitto.conf')
    with open(conf, 'w') as f:
        f.write('listener %d 127.0.0.1\npersistence false\nallow_anonymous true\n' % port)
    broker = subprocess.Popen([shutil.which('mosquitto') or '/usr/sbin/mosquitto', '-c', conf],
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    url = 'mqtt://127.0.0.1:%d/soak' % port
    wrap = ()
    if shutil.which('umockdev-run'):
        data = os.path.join(ROOT, 'tests', 'sensor')
        wrap = ('umockdev-run', '-d', os.path.join(data, 'als.umockdev'), '-p',
                SYSFS + '2=' + os.path.join(data, 'als-flood.pcap'), '--')
    fast = ['sensor_mode=cloud', 'sensor_rescan_s=1']
    ctl = Skyd(args.build, tmp, 'controller',
               ['--sync', url, '--sync-role', 'controller'] + SMALL + fast, wrap)
    fol = Skyd(args.build, tmp, 'follower', ['--sync', url, '--sync-role', 'follower'] + SMALL)
    return broker, ctl, fol


def main():
    p = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    p.add_argument('--minutes', type=float, default=60)
    p.add_argument('--seed', type=int, default=1)
    p.add_argument('--build', default=os.path.join(ROOT, 'build'))
    p.add_argument('--out', default=None, help='also write the samples and summary here')
    args = p.parse_args()
    rng = random.Random(args.seed)
    out = open(args.out, 'w') if args.out else None
    tmp = tempfile.mkdtemp(prefix='skyd-soak-')
    broker, ctl, fol = start_rig(args, tmp)
    daemons = {'controller': ctl, 'follower': fol}
    clients, samples, steps = [], [], 0
    start = time.monotonic()
    next_sample = start
    try:
        while True:
            now = time.monotonic()
            if now >= next_sample:
                minute = (now - start) / 60.0
                for who, d in daemons.items():
                    s = sample(d.pid)
                    samples.append((minute, who, s))
                    line = '%6.1f min %-10s rss %7d KiB  fds %4d  threads %3d  regions %2d  (%d steps)' % (
                        minute, who, s[0], s[1], s[2], s[3], steps)
                    for f in (sys.stdout, out):
                        if f:
                            print(line, file=f, flush=True)
                next_sample += 60
                if minute >= args.minutes:
                    break
            for path, c in list(clients):
                if not c.drain():
                    clients.remove((path, c))
            step(rng, clients, [ctl.sock, fol.sock])
            steps += 1
            time.sleep(rng.uniform(0, 0.2))
    finally:
        for _, c in clients:
            c.close()
        for d in daemons.values():
            d.stop()
        broker.terminate()
        broker.wait()
    for f in (sys.stdout, out):
        if f:
            summary(samples, daemons, f)
    shutil.rmtree(tmp, ignore_errors=True)


if __name__ == '__main__':
    main()
