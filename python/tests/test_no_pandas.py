"""Without pandas: dicts of numpy arrays everywhere; and Ctrl-C."""

import signal
import subprocess
import sys
import time

from conftest import DRIVE, DRIVE_DATA, ROOT

BLOCK_PANDAS = "import sys; sys.modules['pandas'] = None\n"


def run(code, **kw):
    return subprocess.run([sys.executable, "-c", BLOCK_PANDAS + code], capture_output=True, text=True, cwd=ROOT, **kw)


def test_everything_works_without_pandas():
    done = run(
        f"""
import numpy as np, aidnav
assert not aidnav.have_pandas()
g = aidnav.read_gnss({str(DRIVE_DATA / 'gnss_1934_sf.pos')!r})
assert isinstance(g, dict) and isinstance(g['lat_deg'], np.ndarray) and len(g['lat_deg']) == 2197
r = aidnav.process({str(DRIVE)!r}, score=False)
assert isinstance(r.solution, dict) and isinstance(r.warnings, dict)
assert r.result['tracking_rms_m'] < 0.05
assert isinstance(r.scores, dict)
try:
    aidnav.read_gnss({str(DRIVE_DATA / 'gnss_1934_sf.pos')!r}, as_frame=True)
except ImportError as e:
    print('import error:', e)
print('ok')
"""
    )
    assert done.returncode == 0, done.stderr
    assert "ok" in done.stdout and "needs pandas" in done.stdout


def test_ctrl_c_interrupts_a_long_call():
    proc = subprocess.Popen(
        [sys.executable, "-c", "import aidnav, sys\nprint('start', flush=True)\n"
         "try:\n    aidnav.reproduce('anomalies', runs=100_000)\n"
         "except KeyboardInterrupt:\n    print('interrupted', flush=True)\n    sys.exit(3)\n"],
        stdout=subprocess.PIPE, text=True, cwd=ROOT,
    )
    assert proc.stdout.readline().strip() == "start"
    time.sleep(1.0)
    sent = time.monotonic()
    proc.send_signal(signal.SIGINT)
    out, _ = proc.communicate(timeout=30)
    assert proc.returncode == 3 and "interrupted" in out
    # Within a few polls, not after 100 000 runs.
    assert time.monotonic() - sent < 10
