#!/usr/bin/env python3
"""test_readme_examples.py - the README's examples as a reader runs them:
every block between "<!-- example" and "<!-- end example -->" comment lines
of README.md runs, as written, against a real skyd started as `./dev run`
starts it (no arguments, its socket under $XDG_RUNTIME_DIR), with the
build's skyd, skyctl and skyrender first in PATH, in a directory of its own.

A block's indented lines are commands. In a block with "$ " lines, those
are the commands and the lines after each its expected output; a "$ socat"
line opens a transcript, the user's requests between skyd's replies (each
ending with its OK or ACK line), typed one at a time as a reader would.
Every command must exit 0. Output compares line by line: the words
exactly, whole numbers exactly, other figures to a relative 1e-3 (the
README says so), as lavapipe's and a GPU's rounding differ in the last
digits and no more.
  usage: test_readme_examples.py README.md BUILD_DIR
Exits 77 (skipped) without socat or a Vulkan device."""
import os
import re
import select
import shutil
import subprocess
import sys
import tempfile
import threading
import time

RELATIVE = 1e-3
NUMBER = re.compile(r"[-+]?(?:\d+\.\d*|\.\d+|\d+)(?:[eE][-+]?\d+)?")
failures = []


def check(ok, what):
    print(("ok: " if ok else "FAIL: ") + what)
    if not ok:
        failures.append(what)


def same_line(want, got):
    """The words alike and each figure within the tolerance."""
    if NUMBER.sub("#", want) != NUMBER.sub("#", got):
        return False
    for a, b in zip(NUMBER.findall(want), NUMBER.findall(got)):
        if re.fullmatch(r"[-+]?\d+", a) and re.fullmatch(r"[-+]?\d+", b):
            if int(a) != int(b):
                return False
        elif abs(float(a) - float(b)) > RELATIVE * max(abs(float(a)), abs(float(b))):
            return False
    return True


def compare(what, want, got):
    ok = len(want) == len(got) and all(same_line(w, g) for w, g in zip(want, got))
    check(ok, what)
    if not ok:
        print("  README:  " + "\n           ".join(want))
        print("  now:     " + "\n           ".join(got))


def blocks(readme):
    """Each example block's indented lines, without the indent."""
    out, cur = [], None
    for line in open(readme, encoding="utf-8"):
        if line.startswith("<!-- end example"):
            out.append(cur or [])
            cur = None
        elif line.startswith("<!-- example"):
            cur = []
        elif cur is not None and line.startswith("    "):
            cur.append(line[4:].rstrip("\n"))
    return out


def read_line(proc, deadline):
    """One line of proc's stdout, or None at its end or past the deadline."""
    buf = b""
    fd = proc.stdout.fileno()
    while not buf.endswith(b"\n"):
        left = deadline - time.monotonic()
        if left <= 0 or not select.select([fd], [], [], left)[0]:
            return None
        c = os.read(fd, 1)
        if not c:
            return buf.decode() if buf else None
        buf += c
    return buf.decode().rstrip("\n")


def conversation(cmd, lines, env, cwd):
    """A socat transcript: the greeting, then each request and its reply."""
    proc = subprocess.Popen(["bash", "-c", cmd], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                            env=env, cwd=cwd)
    deadline = time.monotonic() + 120
    got = read_line(proc, deadline)
    compare(f"{cmd}: the greeting", lines[:1], [got or ""])
    i = 1
    while i < len(lines):
        request = lines[i]
        j = i + 1
        while j < len(lines) and not re.match(r"(OK|ACK)\b", lines[j]):
            j += 1
        want = lines[i + 1:j + 1]
        proc.stdin.write((request + "\n").encode())
        proc.stdin.flush()
        reply = []
        while True:
            line = read_line(proc, deadline)
            if line is None:
                break
            reply.append(line)
            if re.match(r"(OK|ACK)\b", line):
                break
        compare(f"socat: {request}", want, reply)
        i = j + 1
    proc.stdin.close()
    try:
        check(proc.wait(timeout=30) == 0, f"{cmd} exits 0")
    except subprocess.TimeoutExpired:
        proc.kill()
        check(False, f"{cmd} ends once its input does")


def run(cmd, want, env, cwd):
    """One command line; its exit status, and its output where shown."""
    try:
        p = subprocess.run(["bash", "-c", cmd], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                           env=env, cwd=cwd, timeout=180)
    except subprocess.TimeoutExpired:
        check(False, f"{cmd} ends within 180 s")
        return
    check(p.returncode == 0, f"{cmd} exits 0" +
          ("" if p.returncode == 0 else f" (exit {p.returncode}: {p.stderr.decode().strip()})"))
    if want is not None:
        compare(f"{cmd}: its output", want, p.stdout.decode().splitlines())


def run_block(lines, env, cwd, build):
    # The build's folder where the README names build/ (before the install).
    lines = [re.sub(r"(?<![\w/.-])build/", build + "/", l) for l in lines]
    if lines and lines[0].startswith("$ socat"):
        conversation(lines[0][2:], lines[1:], env, cwd)
        return
    if not any(l.startswith("$ ") for l in lines):
        for l in lines:
            run(l, None, env, cwd)
        return
    cmd, want = None, []
    for l in lines + ["$ "]:
        if l.startswith("$ "):
            if cmd:
                run(cmd, want, env, cwd)
            cmd, want = l[2:], []
        else:
            want.append(l)


def start_skyd(build, env):
    """skyd as ./dev run starts it; its process once it listens, None
    (skipped) without a Vulkan device. A thread reads its log to the end,
    so that it never blocks on a full pipe."""
    skyd = subprocess.Popen([os.path.join(build, "daemon", "skyd")], stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE, env=env)
    said, listening = [], threading.Event()

    def drain():
        for raw in skyd.stderr:
            said.append(raw.decode(errors="replace").strip())
            if "listening on" in said[-1]:
                listening.set()
        listening.set()
    threading.Thread(target=drain, daemon=True).start()
    if listening.wait(60) and skyd.poll() is None and any("listening on" in s for s in said):
        return skyd
    skyd.kill()
    skyd.wait()
    if any("Vulkan" in s or "device" in s for s in said):
        print("skipped: no Vulkan device for skyd: " + "; ".join(said))
        sys.exit(77)
    print("FAIL: skyd did not start: " + "; ".join(said))
    sys.exit(1)


def main():
    readme, build = sys.argv[1], os.path.abspath(sys.argv[2])
    if not shutil.which("socat"):
        print("skipped: socat is missing")
        sys.exit(77)
    examples = blocks(readme)
    check(len(examples) >= 3, f"README.md marks its examples ({len(examples)} blocks)")
    tmp = tempfile.mkdtemp(prefix="skyd-readme.")
    env = dict(os.environ, XDG_RUNTIME_DIR=tmp,
               PATH=os.pathsep.join([os.path.join(build, d) for d in ("daemon", "client", "render")]
                                    + [os.environ.get("PATH", "/usr/bin:/bin")]))
    skyd = start_skyd(build, env)
    try:
        for lines in examples:
            run_block(lines, env, tmp, build)
    finally:
        skyd.terminate()
        skyd.wait()
        shutil.rmtree(tmp, ignore_errors=True)
    if failures:
        print(f"test_readme_examples: {len(failures)} failed")
        sys.exit(1)
    print("test_readme_examples: all passed")


if __name__ == "__main__":
    main()
