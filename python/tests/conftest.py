"""What the Python package's tests share: the real skyd on a private socket
in a fresh directory, ready when it says READY=1 on a notify socket of ours
(as testkit/daemon_harness.h does, never after a sleep), with small tables;
and exit status 77 (skipped, for ctest) where skyd finds no Vulkan device."""

import os
import select
import shutil
import signal
import socket
import subprocess
import tempfile

import pytest

import skyd

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
READY_TIMEOUT_S = 60.0

# testkit/daemon_harness.h's HARNESS_SMALL: these tests are about the
# client, not the tables.
SMALL = ["transmittance_width=64", "transmittance_height=16", "transmittance_steps=16",
         "multiscatter_width=8", "multiscatter_height=8", "multiscatter_steps=8",
         "multiscatter_dirs=2", "skyview_width=32", "skyview_height=16", "skyview_steps=8",
         "aerial_width=8", "aerial_height=8", "aerial_depth=4"]


def built(env, *rel):
    """A binary the build made: from the environment (ctest sets it), else
    under ./build of the checkout (running pytest by hand)."""
    path = os.environ.get(env) or os.path.join(ROOT, "build", *rel)
    return path if os.access(path, os.X_OK) else None


class NoDevice(Exception):
    pass


class Daemon:
    """skyd started on dir/control with args; restartable in the same place."""

    def __init__(self, binary, args):
        self.binary = binary
        self.args = list(args)
        self.dir = tempfile.mkdtemp(prefix="skyd-py-", dir=os.environ.get("TMPDIR") or "/tmp")
        self.socket = os.path.join(self.dir, "control")
        self.log = os.path.join(self.dir, "skyd.log")
        self.proc = None

    def start(self):
        notify = os.path.join(self.dir, "notify")
        if os.path.exists(notify):
            os.unlink(notify)
        ns = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM | socket.SOCK_CLOEXEC)
        ns.bind(notify)
        env = dict(os.environ, NOTIFY_SOCKET=notify)
        with open(self.log, "ab") as log:
            self.proc = subprocess.Popen([self.binary, "--socket", self.socket] + self.args,
                                         stdin=subprocess.DEVNULL, stdout=log, stderr=log,
                                         env=env)
        pidfd = os.pidfd_open(self.proc.pid)
        try:
            poller = select.poll()
            poller.register(ns, select.POLLIN)
            poller.register(pidfd, select.POLLIN)
            while True:
                ready = dict(poller.poll(READY_TIMEOUT_S * 1000))
                if not ready or pidfd in ready:
                    self.proc.kill()
                    self.proc.wait()
                    text = open(self.log, errors="replace").read()
                    if "no Vulkan device" in text:
                        raise NoDevice(text.strip().splitlines()[-1])
                    raise RuntimeError("skyd did not get ready; its log:\n" + text)
                if b"READY=1" in ns.recv(4096):
                    return
        finally:
            os.close(pidfd)
            ns.close()

    def stop(self, sig=signal.SIGTERM):
        if self.proc is not None:
            self.proc.send_signal(sig)
            self.proc.wait()
            self.proc = None

    def cleanup(self):
        self.stop()
        shutil.rmtree(self.dir, ignore_errors=True)


def start_daemon(request, args=SMALL):
    binary = built("SKYD_BINARY", "daemon", "skyd")
    if binary is None:
        pytest.skip("no skyd binary (SKYD_BINARY, or build/daemon/skyd)")
    d = Daemon(binary, args)
    try:
        d.start()
    except NoDevice as e:
        d.cleanup()
        request.config.stash[NO_DEVICE] = True
        pytest.skip("no Vulkan device: %s" % e)
    return d


NO_DEVICE = pytest.StashKey[bool]()


@pytest.fixture(scope="module")
def daemon(request):
    d = start_daemon(request)
    yield d
    d.cleanup()


@pytest.fixture
def client(daemon):
    c = skyd.Client(daemon.socket, timeout=60)
    yield c
    c.close()


@pytest.fixture(scope="module")
def probe():
    path = built("SKYD_PYPROBE", "python", "pyprobe")
    if path is None:
        pytest.skip("no pyprobe (SKYD_PYPROBE, or build/python/pyprobe)")
    return path


def pytest_sessionfinish(session, exitstatus):
    """Tests skipped because the machine has no Vulkan device, none failed:
    77 for ctest, which reports the module skipped rather than passed."""
    reporter = session.config.pluginmanager.get_plugin("terminalreporter")
    stats = reporter.stats if reporter else {}
    if session.config.stash.get(NO_DEVICE, False) and not stats.get("failed") \
            and not stats.get("error"):
        session.exitstatus = 77
