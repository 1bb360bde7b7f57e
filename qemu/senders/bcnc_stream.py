#!/usr/bin/env python3
"""Stream a G-code file to a grbl TCP port with the REAL bCNC sender code, headless.

usage: python bcnc_stream.py HOST:PORT program.nc
           [--override-at SECONDS --override PERCENT] [--override-back-at SECONDS]
           [--timeout SECONDS] [--transcript FILE]

Needs the PyPI package bCNC==0.9.16 plus pyserial, numpy, svgelements and a
Python with tkinter (Debian: python3-tk). No display is used: no Tk root is
ever created, only bCNC's non-GUI classes (Sender, CNC/GCode, controllers).

What runs is bCNC's own code: Sender.open() (connect, "\\n\\n", serialIO thread),
GCode.load()/compile(), Sender.serialIO() (128-byte character counting,
'?' polling every 0.125 s, override bytes via controllers/GRBL1.overrideSet()),
Sender.runEnded()/controllerStateChange()/jobDone() (end-of-job purge).
Only the GUI glue of bmain.Application is reproduced here: run() minus the
canvas/statusbar code, and _monitorSerial() minus the terminal widgets.
Overrides are changed like ControlPage.overrideChange() (the GUI slider):
CNC.vars["_OvFeed"] = value; CNC.vars["_OvChanged"] = True.

Override times count from pressing Run (bCNC then sleeps 1 s before line 1).
Ask for +/-10 steps only if the exact value matters: overrideSet() works from the
last Ov: it saw, and the report answering the same poll still shows the old
value, so asking 120 from 100 sends 0x91 three times (ends at 130).

Prints ONE JSON line on stdout (bCNC's own prints go to stderr);
exit code 0 only if the job ran to its end and no error/ALARM was received.
"""
import argparse
import importlib.util
import json
import os
import sys
import tempfile
import time

T0 = time.time()
OUT = sys.stdout
sys.stdout = sys.stderr          # bCNC prints chatter; keep stdout for the JSON

# --- make bCNC importable the way its __main__.py does --------------------
PRG = os.path.dirname(importlib.util.find_spec("bCNC").origin)
for sub in ("", "lib", "plugins", "controllers"):
    sys.path.append(os.path.join(PRG, sub))

import Helpers  # noqa: E402,F401  installs gettext's _() builtin, needed by bCNC
import Utils    # noqa: E402

# Keep the user's ~/.bCNC and ~/.bCNC.history out of it: read only bCNC.ini.
_tmp = tempfile.mkdtemp(prefix="bcnc-")
Utils.iniUser = os.path.join(_tmp, "bCNC.ini")
Utils.hisFile = os.path.join(_tmp, "bCNC.history")
Utils.loadConfiguration()

from CNC import CNC, WAIT     # noqa: E402
from Sender import Sender     # noqa: E402


class Tap:
    """Wraps bCNC's pyserial object: records what bCNC writes and reads."""

    def __init__(self, ser, app):
        self._ser, self._app = ser, app

    def write(self, data):
        self._app.wire.append((time.time() - T0, "TX", bytes(data)))
        return self._ser.write(data)

    def readline(self):
        raw = self._ser.readline()
        if raw:
            self._app.wire.append((time.time() - T0, "RX", raw))
            self._app.on_line(raw.decode("ascii", "ignore").strip())
        return raw

    def __getattr__(self, name):
        return getattr(self._ser, name)


class HeadlessSender(Sender):
    """bCNC's Sender plus the few things bmain.Application normally provides."""

    def __init__(self):
        self.wire = []               # (t, "TX"/"RX", bytes)
        self.reports = []            # every <...> status report
        self.received_errors = []    # error:/ALARM lines seen anywhere
        self.job_done = False        # Sender.jobDone() (end-of-job purge) returned
        self.lines_sent = 0
        self.expected = None         # _runLines set by run()
        Sender.__init__(self)
        Sender.loadConfig(self)      # as Application.__init__ does (controller=GRBL1)

    # Sender.open() assigns self.serial = serial.serial_for_url(...): wrap it.
    @property
    def serial(self):
        return self.__dict__.get("_serial")

    @serial.setter
    def serial(self, value):
        self.__dict__["_serial"] = Tap(value, self) if value is not None else None

    def on_line(self, line):
        if line.startswith("<"):
            self.reports.append((round(time.time() - T0, 3), line))
        elif "error" in line.lower() or "ALARM" in line:
            self.received_errors.append(
                {"t": round(time.time() - T0, 3), "line": line,
                 "during_job": self.running})

    # --- GUI stubs used by Sender / controllers --------------------------
    def disable(self):               # Sender.initRun(): greys the widgets
        pass

    def enable(self):
        pass

    def event_generate(self, *a, **kw):  # Pn:S cycle-start, _wcsSet status text
        pass

    def acceptKey(self, skipRun=False):  # feedHold(event)/resume(event)
        return True

    def busy(self):
        pass

    def notBusy(self):
        pass

    def checkStop(self):             # GCode.compile() polls it
        return self._stop

    def jobDone(self):
        Sender.jobDone(self)         # "!" + 0x18 + $X ... (purgeController)
        self.job_done = True

    # --- bmain.Application.run(), GUI parts removed ----------------------
    def run(self):
        self.cleanAfter = True
        CNC.vars["errline"] = ""
        self.initRun()                       # running=True, empties queue, sleeps 1 s
        self._runLines = sys.maxsize         # "still queueing" marker for serialIO
        self._gcount = 0
        self._paths = None
        CNC.vars["running"] = True
        CNC.vars["_OvChanged"] = True        # bCNC forces an override check at start
        self._paths = self.gcode.compile(self.queue, self.checkStop)
        if not self._paths:
            self.runEnded()
            raise SystemExit("bCNC compiled no lines from the file")
        self._runLines = self.expected = len(self._paths) + 1  # plus the final WAIT
        self.queue.put((WAIT,))                # wait for Idle at the end

    # --- bmain.Application._monitorSerial(), widgets removed --------------
    def monitor(self):
        while self.log.qsize() > 0:
            msg, line = self.log.get_nowait()
            if msg == Sender.MSG_BUFFER:
                self.lines_sent += 1 if self.running else 0
            elif msg == Sender.MSG_ERROR:    # error:/ALARM: and eval exceptions
                if not any(e["line"] == str(line).strip() for e in self.received_errors):
                    self.received_errors.append(
                        {"t": round(time.time() - T0, 3), "line": str(line).strip(),
                         "during_job": self.running})
        # bmain's end test; Sender.close() (connection lost) zeroes _runLines,
        # which would fake an end, so also require _runLines to be untouched.
        if self.running and self._gcount >= self._runLines == self.expected:
            self.runEnded()
            return True
        return False


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("address", help="HOST:PORT of the grbl TCP server")
    ap.add_argument("program")
    ap.add_argument("--override-at", type=float)
    ap.add_argument("--override", type=int)
    ap.add_argument("--override-back-at", type=float)
    ap.add_argument("--timeout", type=float, default=600.0)
    ap.add_argument("--transcript", help="write every TX/RX chunk (hex) here")
    a = ap.parse_args()

    app = HeadlessSender()
    app.load(a.program)                              # Sender.load -> GCode.load
    try:
        app.open(f"socket://{a.address}", 115200)    # bCNC's own open (≈2 s of sleeps)
    except Exception as e:                           # e.g. connection refused
        OUT.write(json.dumps({"ok": False, "end": f"open failed: {e}"}) + "\n")
        OUT.flush()
        os._exit(2)

    # Like a user: wait until bCNC has seen an Idle report before pressing Run.
    deadline = time.time() + 15
    while CNC.vars["state"] != "Idle" and time.time() < deadline:
        app.monitor()
        time.sleep(0.2)
    time.sleep(0.5)
    app.monitor()

    start = time.time()
    app.run()
    pending = []                                     # (time after start, percent)
    if a.override_at is not None and a.override is not None:
        pending.append((a.override_at, a.override))
    if a.override_back_at is not None:
        pending.append((a.override_back_at, 100))
    pending.sort()

    ended = False
    end_time = None
    why = "timeout"
    while time.time() - start < a.timeout:
        now = time.time() - start
        while pending and now >= pending[0][0]:
            _, pct = pending.pop(0)
            CNC.vars["_OvFeed"] = pct                # = ControlPage.overrideChange()
            CNC.vars["_OvChanged"] = True
        if app.monitor():
            ended, end_time = True, time.time()
        if ended and (app.job_done or time.time() - end_time > 10):
            why = "ended"
            break
        if not ended and any(e["during_job"] for e in app.received_errors):
            why = "error during job"                 # bCNC empties its queue: never ends
            time.sleep(0.5)
            break
        if app.thread is None or app.serial is None:
            why = "connection lost"
            break
        time.sleep(0.2)                              # MONITOR_AFTER = 200 ms in bmain
    elapsed = (end_time or time.time()) - start
    time.sleep(0.7)                                  # let the purge's replies arrive
    app.monitor()

    # stop bCNC's serialIO thread and close (Sender.close() would also send
    # "!" and a purge; the job is over so just drop the connection)
    th = app.thread
    app.thread = None
    if th:
        th.join(2)
    try:
        app.serial.close()
    except Exception:
        pass

    if a.transcript:
        with open(a.transcript, "w") as f:
            for t, d, data in app.wire:
                f.write(f"{t:9.3f} {d} {data.hex(' ')}   {data!r}\n")

    ov_reports, last_ov = [], None
    for t, r in app.reports:
        ov = next((p for p in r.strip("<>").split("|") if p.startswith("Ov:")), None)
        if ov and ov != last_ov:
            ov_reports.append({"t": t, "report": r})
            last_ov = ov
    ok = ended and not app.received_errors
    result = {
        "ok": ok,
        "end": why,
        "lines_sent": app.lines_sent,
        "lines_compiled": len(app._paths or []),
        "elapsed_s": round(elapsed, 3),
        "last_report": app.reports[-1][1] if app.reports else None,
        "ov_reports": ov_reports,            # first report + each change of Ov:
        "reports_seen": len(app.reports),
        "errors": app.received_errors,
        "job_done_purge": app.job_done,
    }
    OUT.write(json.dumps(result) + "\n")
    OUT.flush()
    os._exit(0 if ok else 1)                         # don't wait on bCNC threads


if __name__ == "__main__":
    main()
