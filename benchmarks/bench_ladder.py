"""Benchmark: a whole ladder on the twins, wall time and peak memory (run on demand).

    /work/venv/bin/python benchmarks/bench_ladder.py [--procedure configs/procedures/paper-ladder.yaml]
        [--fog-hz 5000] [--axes outer] [--rates 0.1] [--turns-scale 2] [--seed N] [--out DIR]

Runs `bench run PROCEDURE --yes` as a new user would (the shipped stand, `clock_speed:
max`), and samples the resident memory of the whole process tree (the bench, its
analysis worker) every 0.2 s with psutil. Options rewrite copies of the procedure and
stand: the FOG's rate, a subset of axes or rates, more turns (a longer ladder). Prints
one line: bench time, wall time, peak RSS of the tree, frames lost, exit status.
Goals (issue 27, this 2-core machine): paper ladder <= 120 s wall, <= 500 MB peak RSS of
the process tree; memory flat in duration (a ladder twice as long); 0 frames lost.
Measured (25 Nov 2026, main): the shipped paper ladder completes, bench time 105531 s,
316 s wall, 379 MB, 0 frames lost, exit 0, at load average ~10 on 2 cores (the helper's
branch: 253 s wall, 188 CPU s, 403 MB at load 10). It used to abort at 0.1 deg/s, outer,
half 3: the half was armed 1.8 s after the reversal carried the table over its zero
mark, so the first value (3598.2 s) looked like a whole turn; the counter driver now reads
such a value as this counter has already shown (counter_profiles.first_value_is_a_turn).
Most CPU is the pty channel's kernel time (4 kB per read).
On a quiet machine (25 Nov 2026): 146-153 s wall (120 s measuring, 23 s writing the
result and certificate), then 127 s (118 s measuring, 7 s writing) once the final analysis
took the worker's first look at each pair and the temperatures decoded with it, and the raw
captures were hashed as written; user 84 s + system 87 s of CPU. With the FOG reader's
batches at 512 kB instead of 128 kB: 104, 106 and 110 s wall (128 kB the same hour: 117 s),
384 MB peak, 0 frames lost, exit 0. A pty moves about 75 MB/s with one core (1 GB: 7.2 s of
system time in the reader, plus the kernel's flush work), and the ladder's 7.6 GB of FOG
frames are most of what is left. Keep 8 GB free in the --out folder's file system: `bench
run` refuses to start without room for the plan's raw data.

On a slower 2-core machine (26 Nov 2026, 2.1 GHz Xeon; the quiet suite 1100-1200 s there
against 699 s): 187 s wall, user 187 s + system 83 s (144 % of one core), 10 M voluntary
context switches, 0 frames lost. The stand computed in 16384-sample blocks (its random
numbers still on the 4096 grid): 164 s, user 168 s + system 69 s. In the bench process the
interpreter lock is held about half the time (py-spy --gil); the rest is the pty's 4 kB
reads and writes handing the lock and the cores back and forth, and the analysis worker.
The same machine the next day: 160-177 s (four runs; the interpreter's switch interval
5 ms instead of 0.5 ms: 164 and 160 s, no change). By thread (CPU s): bench thread 78,
each FOG reader 51 (user 185 + system 110 ns a frame with one FOG), each FOG twin writer
15, analysis worker 33, CAN 6; 145 s measuring, 4 s for the last pairs, 12 s writing the
result and certificate. Half of the 212 M frames are the FOG of the axis not under test,
recorded at rest and analysed nowhere: the outer axis alone (`--axes outer`) takes 49 s,
the inner alone 44 s, 93 s together against 160 s for both in one run.
With the stand's cos calls cut (recurrence and rotation, d824d01): 170 s, 387 MB, 0 lost;
system-wide (/proc/stat) user 147 + nice 26 (the worker) + system 80 core-s, idle 73 of
340 (22 %); the outer 0.1 deg/s pair alone 53 s with 32 % idle and the interpreter lock
held ~40 % of the time (py-spy --gil): bound by the hand-offs between threads, not by
one resource. The serial tail is ~16 s: the last pair's first look (~4 s) and the
certificate (its matplotlib PNGs ~0.5 s a figure, 40 % of that constrained layout;
fpdf's table cells ~2 s).

27 Nov 2026, same VM (its speed drifts ~20 % within an hour: compare only runs
interleaved the same hour). The FOG reader's batches had ended at the pty's first empty
moment (pyserial's ttys return 0 bytes, not EAGAIN, so the gap wait never ran): mostly
16-64 kB. On a stepped clock a batch now waits for the bytes the twin has sent
(drivers.clock.in_flight): 131 s against 167 s, CPU 194 against 247 core-s. With each
half's FOG window read in the worker as the half completes (the last first look's wait
~6 s -> 0.5 s) and the twin's encoder 2x faster: 155 and 134 s against 182 and 169.5 s
for the session's start (ff6f0d9), interleaved; 383-385 MB, 0 lost. Still above 120 s
here: the stepping thread (the stand's samples, taking the interpreter lock back after
each numpy operation, and the encoding) sets the pace while measuring, and ~14 s of
result and certificate writing follow the last pair.

27 Nov 2026, later (HEAD bb8bbff): 115 s at 02:17, then 130, 134, 141 and 144 s the same
night (385-388 MB, 0 lost). The session's start (1eef433) interleaved with HEAD: 134 and
142.5 s against 141 and 144 s: this session's changes (the worker's threads all at its
nice, the stand's generators without a SeedSequence per block) are inside the VM's drift.
(The worker's BLAS on one thread was tried and dropped: a Gram product's last bits
depend on BLAS's thread count, and `bench analyze` must rebuild result.json exactly.)
`perf record -a` in the middle of the ladder, by thread: the FOG readers 28 % of both
cores, the stepping thread 22 %, the analysis worker 19 %, the twins' writers 11 %,
kernel workers 3 %, idle 9 % (20 % over the run, 50 % in the certificate tail). Kernel
time is a quarter of the CPU: context switches 6 %, wake-ups 5 %, the pty's flush work
queued per write 2.4 %, copies ~4 %: n_tty hands over 4 kB a read, each needing a kernel
worker run and a reader wake-up (the slave is in n_tty's real-raw mode already).

27 Nov 2026, the next session (HEAD 54eb1d9, then 37cb62e; this VM): 138 s at 05:01
(starting 3.6 s, measuring 117.8 s, the stop and the last analyses 3.0 s, writing the
outputs 13.1 s; 386 MB, 0 lost) and 146 s at 06:11 (2.9 / 128.3 / 2.3 / 11.6 s).
Measuring, by part: each 0.1 deg/s unit ~43-47 s, the high-rate units 16 s (outer) and
11 s (inner). The outer 0.1 deg/s unit alone (`--axes outer --rates 0.1`, one FOG
streaming) measures in 22-27 s: the FOG of the axis not under test, streaming at rest
through the other axis's units, costs about 40 s of the ladder. Writing the outputs:
the document 3.4-3.7 s (8 figures), HTML 0.04 s, PDF 5.1-5.4 s (300 tables), the DCC
~1.5 s; the DCC embeds the PDF, so these run one after another. Tried on the outer
0.1 deg/s unit (interleaved with HEAD, compared on the measuring phase) and left out:
stand blocks of 65536 samples; a 16 MB FOG lead and 60 s steps; a helper process
pumping each pty into a 1 MB pipe (reader, and the twin's writer too: the driver and
the twin then make one call a MB instead of one per 4 kB); the stand's next block
computed ahead in a thread (bit for bit the same blocks). None moved the measuring
phase beyond the VM's noise (<= 5 %). The stand's generation cut by ~2/3 (wrong
numbers, as a measurement only) made it ~12 % faster, and made nearly free (the
commanded rate integrated, nothing else) ~25 % on that unit and 13 % on the full
ladder (measuring 115 s against 132 s): the stand is partly on the critical path, and
only a process of its own would take it off the interpreter lock.
The raw pty on this VM moves 180-240 MB/s on one core (dd into the master, Python
reading the slave), against ~50 MB/s a FOG in the ladder: the channel is not at its
bandwidth; the bench process's threads and the interpreter lock set the pace.

27 Nov 2026, 9514c80: each axis's FOG streams for that axis's steps only (the ladder
opens it after the axis's prompt, closes it when the next axis begins; the twin sends
nothing while no reader has the port). Interleaved on this VM, 08:20-08:26: 100 s and
110 s (measuring 74.1 and 84.6 s, writing the outputs 18 s) against 161 s for 55607bc
between them (measuring 135.2 s); 381-383 MB against 387 MB, 0 lost, exit 0; CPU over
the run user 92-101 + nice 28-31 (the worker) + system 30-36 core-s against 138 + 31 +
75. First run at 07:40: 107 s (measuring 81.7 s), 378 MB. The raw FOG captures: 3.6 GB
instead of 7.6 GB. `--profile` at 1bd2298 (09:25, 130 s with cProfile's overhead), CPU s
by thread: bench thread 96.2 (the stand's samples 42.5, the drive twins' ticks 20.3, the
FOG twins' encoding 11.1; 15.5 s of real time waiting for participants), both FOG readers
31.6 (26 Nov: ~51 each), both twin writers 13.4 (26 Nov: ~15 each), analysis worker 30.5,
CAN 9.4. The stand still computes the idle axis's samples (at rest) for its drive and
counter twins: part of the 42.5 s.

29 Nov 2026 (issue 62; this VM shared, load 5-14 throughout: walls not comparable with
the above). `--profile --axes outer` (141.5 s with cProfile, load ~8), CPU s by thread:
bench thread 48.7 (the stand's samples 16.5; the FOG twin's encoding 13.8, half of it the
IMU side channels and their draws; the drive twins' ticks 3.9; the journal 0.9; the
result 6.9, of which 4.8 importing scipy.stats and 1.0 the averaged figures' Monte Carlo,
run four times each; the certificate ~13), FOG reader 20.6, analysis worker 14.8, FOG
twin writer 7.0, CAN 3.5; the clock waited 45.1 s of real time for the reader to drain.
The quantiles from scipy.special (no scipy.stats in the bench or the worker) and that
Monte Carlo run once: the whole paper ladder's result.json and raw captures unchanged
(digests of both equal, two runs each), peak RSS of the tree 284 MB against 320 MB, CPU
170.6 against 188.0 core-s (medians of 2 interleaved, 0.91x), wall 227 against 236 s
(load 8-14). Tried and dropped: the acquisition's clock sleeps a whole turn instead of a
quarter (fewer drains of the FOG channel) changed result.json and the raw captures.

29 Nov 2026, 18:37-18:55 (helper-23, issue 62; main dd8a4c7; this VM shared with six
agents, load 0.5 rising to 8-9 during the reference run, 12-22 during the profiles: CPU
seconds are the figures to use). `bench run` of the paper ladder under /usr/bin/time -v:
201.7 s wall, user 116.7 + system 37.0 = 153.7 CPU s, max RSS 257 MB (the largest
process); phases: starting 4.8 s, measuring 165.0 s, the last analyses 0.2 s, writing the
outputs 30.8 s. `--profile` (cProfile, load ~15; 429 s wall): CPU s by thread: bench
thread 99.8 (cumulative: the stand's samples 49.9, the FOG twins' encoding 31.9, the
drive twins' ticks 27.1, all inflated by cProfile), analysis worker 42.8, FOG readers
41.8, FOG twin writers 20.1, CAN 18.0; the clock waited 131 s of real time for the
participants (the FOG channel) to settle. Without a profiler (/tmp micro-benchmark of
the same AxisModel and FogTwin code, no pty): the stand and the encoding cost 1.1 CPU s
per 3600 s of bench time for both axes, ~32 CPU s for the ladder's 105,531 s (a resting
axis 0.04 s per 1000 s, a turning one ~0.25 s). Decoding: ~14 M frames/s (~7.5 CPU s for
the ladder's 106 M frames, paid twice: the live reader and the worker's re-decode of the
capture), a third of it the CRC's table gathers (33 ns a frame at best; a flat table, a
transposed index, larger joined buffers and one-pass field extraction were tried on the
decoder, bit for bit the same, none faster). SHA-256 of the captures ~1 GB/s (~4 CPU s).
The pty alone (benchmarks/bench_fog_channel.py): 56-72 MB/s at this load (1.5-2 CPU s per
400 MB), 6-31 MB/s while another thread holds the interpreter lock half the time, against
0.6-2.3 GB/s through a socket pair: its 4 kB n_tty reads (os.splice from the slave also
returns 4095 bytes a call; os.sendfile from it: EINVAL) made it the suspect. Tried, not
kept (19:32-19:45, interleaved, load 13-34): the FOG twin and driver on a Unix socket
pair instead of the pty (an experiment, not committed): 370.6 s wall, 160.6 + 30.5 = 191.1
CPU s, measuring 279.5 s, against the pty's 353.1 s, 157.7 + 42.0 = 199.7 CPU s,
measuring 270.4 s. The socket pair saved ~11 s of system time and no wall time here:
the channel is not what sets the pace under this load, the CPU work of every thread is
(at load 13-34 a 2-core VM gives the run a fraction of a core). Both runs' result.json
equal the reference's value for value but for the FOG port's name in
instruments.*.fog (the raw captures' digests equal): that text carries /dev/pts/N, which
follows the machine's other ptys, not the seed.

30 Nov 2026, 01:06-01:17 (helper-43, issue 62; main 60f6aeb then h43 one after the other,
load 7-14, so not an acceptance figure): main 375 s wall (starting 13.7, measuring 296.7,
writing 62.8 s), user 174.9 + system 47.3 = 222.2 CPU s, 427 MB; h43 (the FOG drained
when its driver reads instead of at the end of every wait, chunks encoded together, the
idle twin writer asleep on its port) 272 s wall (7.3 / 214.6 / 49.5 s), user 143.2 +
system 42.4 = 185.7 CPU s (0.84x), 425 MB, 0 frames lost; result.json equal value for
value (raw captures' digests too), but for procedure_file's digest (this script writes
the stand's temporary path into the procedure). At load 7-14 the pty's byte rate is not
the floor (3.8 GB at 65 MB/s would be 58 s): every thread's CPU work is. With the idle
twin writers asleep on their ports too (7fe9a63), 01:38-01:41 at load 10 falling to 7:
208 s wall (5.7 / 177.0 / 24.7 s), user 108.5 + system 36.1 = 144.6 CPU s, 430 MB, 0 lost,
result.json equal again. main again right after (01:42-01:47, load 5-9): 289 s wall
(7.1 / 232.7 / 47.5 s), 139.6 + 46.5 = 186.1 CPU s, 430 MB: h43 0.78x the CPU, 0.76x the
measuring phase. Still far from 60 s at this load; an idle machine's figure is to be taken.
Idle, 30 Nov 2026: main bd4f626 at 00:37 (load ~2 at the end, the demo benchmark before
it): 127 s wall (starting 2.8, measuring 113.3, stopping 1.8, writing 8.4 s), 425 MB;
main eb82d06 at 02:40 (load 0.5 -> 1.8): 83 s wall (1.8 / 71.6 / 2.8 / 5.7 s), 433 MB,
0 frames lost, exit 0; bd4f626 again at 03:11, idle: 85 s (1.8 / 74.4 / 2.5 / 5.4 s),
432 MB (the 127 s of 00:37 was the machine's state then: helper-43's change is 0.78x of
the CPU at load, ~2 % of the wall when idle). The goal (60 s) not met: the measuring phase is the threads' CPU
(bench thread's drive ticks and FOG encoding, the readers' decode, the CAN notifiers).

30 Nov 2026, 03:27-04:36 (issue 62). py-spy (--threads --idle) on c3e36b6, idle: the
stepping thread busy 57 s (the stand's samples 27.5, the FOG encoding 14.4, the drive
ticks 4.4, the outputs 6.4) and 34 s waiting in the clock's settles for the FOG channel;
the channel moved only while the stepping thread waited: a pty's reads are 4 kB and its
writes ~11 kB (13.8 kB fit in it), each taking the interpreter lock back, and a pty pair
that moves 157-237 MB/s alone moved 7-18 MB/s beside a thread running Python (/tmp
micro-benchmark: 11.4 MB/s with both ends threads, 34.5 with the reader a process, 237
with both ends out of the lock). Changed: the twin writes a chunk in one blocking call
(sims/fog_line.py `_write_some`), the driver reads its pty through a pump process into a
1 MiB pipe (drivers/port_pump.py), the wake pipe is written only while the twin's writer
sleeps, and the FOG of the axis not under test draws no noise (AxisChunk.fog_dps made on
first use). Interleaved at load ~3 (another agent's tests): 110 s (c3e36b6) against 92 s;
idle at 04:28-04:34: c3e36b6 67 s, the change 68, 70 and 67 s (measuring 55-58 s, the
last analyses 3.6-4.2 s, writing 5.1-5.9 s), 437-442 MB, 0 lost, result.json equal value
for value: the gain is under load; idle, this VM ran c3e36b6 at 67 s where it had run the
same code at 83-85 s two hours before (its speed drifts ~20 %). CPU by thread, idle
(/proc, the change): stepping thread 38.8 s, analysis worker 21.8, FOG readers 19.2, pumps
11.6 (10.2 of it the kernel's tty reads, which the readers paid before), CAN notifiers
3.3, twin writers 5.4; 104 CPU s in 72 s of wall on 2 cores, with ~11 s of it serial
(starting, the worker's last pairs, the certificate): 60 s needs ~15 % less CPU, not more
overlap. Where: the worker decodes the whole capture again (~8 s), the stand's normals
(~6 s) and the FOG encoding (~13 s) in the stepping thread.

30 Nov 2026, 05:41-06:45 (issue 62; main 6680c14). Idle VM, load only this benchmark's
own: 62-66 s until 06:00 (five runs), then 57-62 s (ten runs) as the VM's speed moved
(phases e.g. 1.3 / 48.8 / 3.2 / 4.1 s at 58 s), 432-436 MB, 0 lost. vmstat over one run: user 46 %,
system 28 %, idle 17 % of both cores; idle 25-30 % for stretches (the first half of
each 0.1 deg/s unit, when the analysis worker has nothing to read), ~5 % elsewhere.
The outer 0.1 deg/s unit alone (`--axes outer --rates 0.1`), CPU and run-queue wait by
thread (/proc/<tid>/stat and schedstat): stepping thread 13.0 CPU s and 7.8 s waiting
for a core, FOG reader 6.6 (7.7), pump 6.2 (3.5), twin writer 1.5 (6.1), the worker 8.8
(4.2); 38.6 CPU s in 28.9 s. The interpreter lock was held 8.6 s of it (py-spy --gil;
the stepping thread 5.5 s): the threads wait for a core, not for the lock, and the
clock's settles waited 2.1 s. Tried on branches, not merged (result.json equal value
for value, raw captures byte-identical in each):
- the FOG frames encoded by the twin's writer thread (a job of the stepping thread's
  draws and settings, sims/fog_frames.py on branch h47-job): the unit measured 22.3 and
  20.2 s against 19.5 and 19.7 s for main;
- the interpreter's switch interval 5 ms instead of 0.5 ms: 20.6 and 20.9 s against 19.8
  and 20.3 s;
- decoding once (branch h47): the live reader logs its decoded samples (four column files
  in RUN_DIR/.scratch, written from its sample store's memory) and the worker reads a
  half's window there instead of decoding the capture again. The worker's tail after the
  last unit fell from 3.2-3.5 to 2.0-2.5 s, but the bench process paid for the writes
  (measuring +1 s with 13-byte rows built per batch; the writing phase +0.8 s, deleting
  1.9 GB of log, with zero-copy columns): 60 and 59 s against 60 and 58 s for main,
  interleaved. The worker runs at nice 10 on what the bench leaves: its CPU is not the
  measuring phase's.
Acceptance run (06:22-06:31, main 6680c14, each run started at a 1-minute load average
below 0.3, nothing else running): 61, 58 and 57 s, median 58 s (measuring 51.5 / 49.1 /
47.3 s), 433-434 MB, 0 lost, exit 0. The pump left out (branch h49) and the FOG reader,
its pump and the twin's writer at nice +3 (branch h48), interleaved with main the same
quarter hour: 58 and 57 s, 58 and 58 s, against 60 and 59 s: inside the VM's noise, not
merged. The issue's base fa2ce26 the same hour: 79 s (1.8 / 65.8 / 2.0 / 8.8 s), 319 MB.
Its result.json and main's: the raw captures byte-identical; outside the budgets and the
procedure file's digest (this script writes a temporary path), 272 values differ in the
last digits (at most 8.6e-12 relative, intra-turn and Allan figures), and all of them are
fa2ce26's own: `bench analyze` of its run with fa2ce26's code and OPENBLAS_NUM_THREADS=1
gives main's numbers exactly (fa2ce26 let BLAS use both cores, so its last digits
followed the machine; bench/analysis/blas.py pins one thread since). The budgets, matched
by their key, differ in 70 dof_eff values in the last digit (issue 56's nu_eff with the
correlations) and in the rows other issues added or renamed.

`--profile` runs the ladder in this process instead and says where the CPU time goes,
by component: the bench thread (the engine, the clock's steps, the stand's samples,
the FOG twins' encoding, the drive twins' ticks: split by cProfile), the FOG twins'
writer threads (the channel), the FOG drivers' reader threads (decode and the raw
capture), the CAN threads, the analysis worker process, and the real time the clock
waited for participants to settle.
"""

from __future__ import annotations

import argparse
import cProfile
import datetime as dt
import io
import json
import os
import pstats
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

import psutil
import yaml

ROOT = Path(__file__).resolve().parent.parent


def tree_rss_bytes(proc: psutil.Process) -> int:
    total = 0
    for p in [proc, *proc.children(recursive=True)]:
        try:
            total += p.memory_info().rss
        except (psutil.NoSuchProcess, psutil.AccessDenied):
            pass
    return total


def prepare(args: argparse.Namespace, tmp: Path) -> Path:
    proc_path = (ROOT / args.procedure).resolve()
    proc = yaml.safe_load(proc_path.read_text())
    stand_path = (proc_path.parent / proc["stand"]).resolve()
    stand = yaml.safe_load(stand_path.read_text())
    if args.seed is not None:
        stand.setdefault("sim", {})["seed"] = args.seed
    if args.fog_hz:
        for ax in stand["axes"].values():
            if ax.get("fog"):
                ax["fog"]["rate_hz"] = args.fog_hz
    if args.axes:
        proc["axes"] = {a: s for a, s in proc["axes"].items() if a in args.axes}
    if args.rates:
        for s in proc["axes"].values():
            s["rates_dps"] = [r for r in s["rates_dps"] if r in args.rates]
    if args.turns_scale != 1:
        proc["turns"] = int(proc.get("turns", 5) * args.turns_scale)
        proc["static_record_s"] = proc.get("static_record_s", 60) * args.turns_scale
    (tmp / "stand.yaml").write_text(yaml.safe_dump(stand, sort_keys=False))
    proc["stand"] = str(tmp / "stand.yaml")
    out = tmp / "procedure.yaml"
    out.write_text(yaml.safe_dump(proc, sort_keys=False))
    return out


#: cProfile's cumulative time of these functions (bench thread), by component
_MAIN_PARTS = {
    "stand samples (sims/stand.py _generate)": "_generate",
    "FOG twin encoding (sims/fog_twin.py _on_chunk)": "_on_chunk",
    "drive twin ticks (sims/drive_twin.py _tick)": "_tick",
    "clock settle waits (sims/clock.py _settle)": "_settle",
    "journal (bench/core/journal.py)": "journal.py",
    "analysis in the bench thread (procedures analysis)": "analysis.py",
}


def _thread_cpu(stop: threading.Event, out: dict[str, float]) -> None:
    """Sample the CPU time of every thread of this process by name (threads end)."""
    me = psutil.Process()
    while True:
        names = {t.native_id: t.name for t in threading.enumerate()}
        seen: dict[int, float] = {}
        for th in me.threads():
            seen[th.id] = th.user_time + th.system_time
        for tid, cpu in seen.items():
            key = f"{names.get(tid, '?')}#{tid}"
            out[key] = max(out.get(key, 0.0), cpu)
        for ch in me.children(recursive=True):
            try:
                c = ch.cpu_times()
                out[f"worker#{ch.pid}"] = max(out.get(f"worker#{ch.pid}", 0.0),
                                              c.user + c.system)
            except psutil.Error:
                pass
        if stop.wait(0.5):
            return


def profile(procedure: Path, out: Path) -> None:
    sys.path.insert(0, str(ROOT))
    from bench.app.commands import run_session
    from bench.core.journal import RunDir
    from bench.core.loader import load_config

    cfg = load_config(procedure)
    run = RunDir.create(out, cfg.procedure_path, cfg.stand_path)
    seen: dict[str, object] = {}
    cpu: dict[str, float] = {}
    stop = threading.Event()
    sampler = threading.Thread(target=_thread_cpu, args=(stop, cpu), daemon=True)
    sampler.start()
    prof = cProfile.Profile()
    t0 = time.monotonic()
    prof.enable()
    status = run_session(cfg, run, yes=True,
                         on_sim_started=lambda sim: seen.setdefault("sim", sim))
    prof.disable()
    wall = time.monotonic() - t0
    stop.set()
    sampler.join()
    if os.environ.get("BENCH_LADDER_PSTATS"):   # for snakeviz or pstats: the bench thread
        prof.dump_stats(os.environ["BENCH_LADDER_PSTATS"])
    stats = pstats.Stats(prof, stream=io.StringIO())
    cum: dict[str, float] = {}
    for (file, _line, func), (_cc, _nc, _tt, ct, _callers) in stats.stats.items():
        for label, key in _MAIN_PARTS.items():
            if key == func or (key.endswith(".py") and file.endswith(key)):
                cum[label] = max(cum.get(label, 0.0), ct)
    groups: dict[str, float] = {}
    for key, t in cpu.items():
        name = key.split("#")[0]
        group = ("bench thread (all of the above, and the rest)" if name == "MainThread"
                 else "FOG twin writers (the pty channel)" if name.startswith("fog-twin")
                 else "FOG driver readers (decode, raw capture)" if name.startswith("fog-")
                 else "analysis worker process" if name == "worker"
                 else "sha256 of the raw files" if name.startswith("sha256")
                 else "CAN (python-can, canopen, heartbeats)" if name.startswith(
                     ("Thread", "can", "heartbeat", "drive-twin"))
                 else f"other threads ({name})")
        groups[group] = groups.get(group, 0.0) + t
    clock = seen.get("sim")
    c = getattr(clock, "clock", None)
    print(f"status {status}, wall {wall:.1f} s, bench time {getattr(c, 'now', lambda: 0)():.0f} s, "
          f"clock steps {getattr(c, 'steps', '?')}")
    print("CPU seconds by thread group:")
    for g, t in sorted(groups.items(), key=lambda x: -x[1]):
        print(f"  {t:8.1f}  {g}")
    print("bench thread, cumulative seconds (cProfile):")
    for label, t in sorted(cum.items(), key=lambda x: -x[1]):
        print(f"  {t:8.1f}  {label}")
    print(f"  {getattr(c, 'settle_wait_real_s', 0.0):8.1f}  real time the clock waited for "
          f"participants to settle")


def phases(events: list[dict[str, Any]], wall_s: float) -> str:
    """The run's wall time by phase, from events.jsonl's UTC stamps.

    The total alone misleads an A/B: the end of a run waits for the analysis worker's
    last first looks (it runs at a lower priority, so a faster measurement can leave it
    more to do at the end) and then writes the result and certificate, and both move
    the total by as much as a change to the measurement itself. Measured on
    `--axes outer --rates 0.1` (27 Nov 2026): 24 s measuring, 10 s waiting for the pair's
    analysis, 6 s writing, 3 s starting.
    """
    def at(e: dict[str, Any]) -> float:
        return dt.datetime.fromisoformat(e["utc"]).timestamp()

    first = next((e for e in events if e["event"] == "step_start"), None)
    stops = [e for e in events if e["event"] == "step_start" and e.get("action") == "stop"]
    done = [e for e in events if e["event"] == "completed"]
    end = [e for e in events if e["event"] == "exit"]
    if not (events and first and stops and done and end):
        return "phases: not known (the run did not complete, or its plan has no stop step)"
    start_s = wall_s - (at(end[-1]) - at(events[0]))      # process start to session start
    measuring_s = at(stops[-1]) - at(first)               # first step to the last stop step
    analyses_s = at(done[-1]) - at(stops[-1])             # the stop and the last first looks
    writing_s = at(end[-1]) - at(done[-1])                # result.json, certificate, records
    return (f"phases: starting {start_s:.1f} s, measuring {measuring_s:.1f} s, stopping and "
            f"the last analyses {analyses_s:.1f} s, writing the outputs {writing_s:.1f} s")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--procedure", default="configs/procedures/paper-ladder.yaml")
    ap.add_argument("--fog-hz", type=float, default=None, help="every FOG's rate_hz")
    ap.add_argument("--seed", type=int, default=None,
                    help="the stand's sim seed (default: the stand file's)")
    ap.add_argument("--axes", nargs="*", default=None)
    ap.add_argument("--rates", nargs="*", type=float, default=None)
    ap.add_argument("--turns-scale", type=float, default=1.0, help="2: a ladder twice as long")
    ap.add_argument("--out", type=Path, default=None, help="keep the run directory here")
    ap.add_argument("--profile", action="store_true",
                    help="run in this process and say where the time goes")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory(prefix="bench-ladder-") as tmp_s:
        tmp = Path(tmp_s)
        procedure = prepare(args, tmp)
        out = args.out or tmp / "runs"
        if args.profile:
            profile(procedure, out)
            return 0
        env = {**os.environ, "PYTHONPATH": str(ROOT)}
        t0 = time.monotonic()
        p = subprocess.Popen([sys.executable, "-m", "bench", "run", str(procedure), "--yes",
                              "--out", str(out)], cwd=ROOT, env=env, text=True,
                             stdout=subprocess.PIPE, stderr=subprocess.DEVNULL)
        ps = psutil.Process(p.pid)
        peak = 0
        while p.poll() is None:
            peak = max(peak, tree_rss_bytes(ps))
            time.sleep(0.2)
        wall = time.monotonic() - t0
        stdout = p.stdout.read() if p.stdout else ""
        run_dir = Path(stdout.strip().splitlines()[-1]) if stdout.strip() else None
        bench_s = lost = load = None
        split = "phases: no run directory"
        if run_dir and (run_dir / "events.jsonl").exists():
            ev = [json.loads(x) for x in (run_dir / "events.jsonl").read_text().splitlines()]
            split = phases(ev, wall)
            done = [e for e in ev if e["event"] == "completed"]
            bench_s = done[-1]["t_s"] if done else None
            lost = sum(int(e.get("fog_lost", 0)) for e in ev if e["event"] == "acquire")
        load = os.getloadavg()[0]
        fog = f"{args.fog_hz:g} Hz" if args.fog_hz else "stand's rate"
        print(f"{Path(args.procedure).stem} (FOG {fog}, axes {args.axes or 'all'}, rates "
              f"{args.rates or 'all'}, turns x{args.turns_scale:g}): bench time "
              f"{bench_s if bench_s is None else round(bench_s)} s, wall {wall:.0f} s, "
              f"peak RSS of the process tree {peak / 2**20:.0f} MB, FOG frames lost {lost}, "
              f"exit {p.returncode}, load average at the end {load:.1f}")
        print(split)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
