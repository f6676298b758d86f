"""The rate ladder's starter files for `bench init` (bench/app/starter.py): a commented
single-axis stand (drive, counter, FOG) and a procedure that validate; without --real
the stand runs on the twins (a `sim:` block), so `bench run DIR/procedure.yaml --yes`
works at once; --real leaves out `sim:` and writes the keys a real bench must state.

Every key the certificate needs and only the laboratory knows (serials, calibration
certificates, the specification's source, the mains frequency; with --real also the
calibrated numbers of the time tie, the timebase and the zero-mark sensor) is written as
a placeholder, `"TO FILL IN: what goes there"` (bench/core/placeholders.py), so
`bench validate` lists each by file, line and key rather than the certificate flagging
its absence after a run. The twins report the serials the placeholders name, so the
identities agree once the laboratory copies them in.
"""

from __future__ import annotations

#: what the starter's twins report as identity (sim.axes.main.serials): the stand file's
#: placeholders name them, so a filled-in starter states what the run reads back
TWIN_COUNTER_SERIAL = "MY61000001"
TWIN_DRIVE_SERIAL = 61001

HEAD = """\
# Values "TO FILL IN: ..." are yours to write (one per line, replace the quoted text):
# `bench validate procedure.yaml` lists each by file, line and key. Until filled in a
# key counts as left out: {meanwhile}
"""

STAND_HEAD = """\
# The stand: the rate table, its instruments and their limits (docs/configuration.md,
# `bench schema stand`). One file per bench; procedures name it with `stand:`.
stand:
  maker: Example Tables Ltd          # the table under test: maker, model, serial
  model: ET-1 single-axis rate table
  serial: "0001"                     # quoted: a serial is text, even when it is digits
  location: calibration room 1
mains_hz: "TO FILL IN: the lab's mains frequency, 50 or 60 Hz{mains_hint}"
axes:
  main:                              # your name for the axis; procedures use it
    drive:                           # the servo drive, CANopen CiA 402
      interface: {interface:<19} # python-can interface (socketcan, pcan, kvaser...)
      channel: {channel:<21} # python-can channel
      node_id: 2
      max_rate_dps: 400              # the table's rate limit: no command exceeds it
      max_accel_dps2: 200            # its acceleration limit
      counts_per_rev: 1048576        # encoder counts per revolution
      serial: "TO FILL IN: the drive's serial, quoted: identity object 0x1018:4{drive_hint}"
{drive_extra}\
    counter:                         # times the zero-mark pulses, one per turn
      resource: "{resource}"
      model: keysight-53230a         # or pendulum-cnt-91 (time stamps); bench schema stand
      serial: "TO FILL IN: the counter's serial, its *IDN? reply's third field{counter_hint}"
      level_v: 2.5                   # absolute trigger level of the zero-mark pulse, V
      slope: POS
      trigger_jitter_s: {jitter:<12} # the zero-mark sensor's edge jitter, std
      reference: external            # timebase: set at connect and read back
      timebase_limit_rel: {timebase:<10} # the external 10 MHz reference's limit (its certificate)
      calibration:                   # the counter's calibration: the results rest on it
        certificate: "TO FILL IN: the counter's calibration certificate number"
        issuer: "TO FILL IN: the laboratory that issued it"
        due: "TO FILL IN: its calibration due date, YYYY-MM-DD"
        traces: "time interval: timebase and interpolator to the SI second"
      time_tie:                      # how the counter's start is placed on the FOG's time
        source: fog-sync             # FOG sync output -> counter EXT trigger
        sync_period_s: 5.0           # FOG time between sync pulses
        latency_s: {latency:<17} # calibrated sync-to-trigger latency
        latency_u_s: {latency_u:<15} # its standard uncertainty
    fog:                             # the reference gyro mounted on the table
      port: {port}
      baudrate: 921600
      format: kvh-a                  # KVH "format A" frames
      axis: z                        # the FOG axis along the table axis
      rate_hz: 1000                  # output rate
      range_dps: 490
      units: deg/s                   # what its rate fields carry (required)
      configure: set                 # set the units at connect and read them back
      model: "TO FILL IN: the FOG's maker and model, as on its label{fog_hint}"
      serial: "TO FILL IN: the FOG's serial, from its label (compared with its ?IS answer)"
traceability:                        # references the bench uses but does not drive
  - item: 10 MHz reference at the counter's Ref In (its limit is timebase_limit_rel)
    serial: "TO FILL IN: the reference's serial"
    certificate: "TO FILL IN: its calibration certificate number"
    issuer: "TO FILL IN: the laboratory that issued it"
    due: "TO FILL IN: its calibration due date, YYYY-MM-DD"
    traces: "frequency to the SI second"
  - item: zero-mark sensor (its edge jitter is trigger_jitter_s)
    serial: "TO FILL IN: the sensor's serial"
    certificate: "TO FILL IN: the certificate of its edge-jitter measurement"
    issuer: "TO FILL IN: the laboratory that issued it"
    due: "TO FILL IN: its calibration due date, YYYY-MM-DD"
    traces: "edge-timing jitter to the SI second"
"""

SIM_DRIVE = """\
      heartbeat_ms: 200
      watchdog_ms: 1500
"""

SIM_BLOCK = f"""\
sim:                                 # the twins' truth; delete this block on a real bench
  seed: 1
  clock_speed: max                   # as fast as the twins keep up
  axes:
    main:
      rate_bias_rel: 3.0e-7          # mean table rate = set x (1 + this)
      harmonics:                     # once-per-rev rate ripple
        - {{order: 1, amplitude_rel: 8.6e-4, phase_deg: 40}}
      mains: {{frequency_hz: 50, amplitude_dps: 2.0e-4, phase_deg: 0}}
      rate_noise_dps: 1.0e-4
      turn_jitter_s: 27.0e-9
      serials: {{counter: {TWIN_COUNTER_SERIAL}, drive: {TWIN_DRIVE_SERIAL}}}   # what the twins report
      fog: {{scale: 1.0003, bias_dps: 0.002, misalignment_deg: 0.2,
            noise_dps: 0.01, bias_drift_dps_per_h: 0.001}}
"""

PROCEDURE = """\
# A procedure: what to measure (docs/configuration.md, `bench schema procedure
# rate-ladder`). Check it with `bench validate`, see its bench time with `bench plan`.
procedure: rate-ladder
title: Periodic recertification, main axis
stand: stand.yaml                    # relative to this file
turns: 4                             # whole turns timed per rate and direction (even: +-+
                                     # splits the + turns in two equal halves)
sequence: "+-+"                      # + half, - half, + half: a linear FOG drift cancels
static_record_s: 30                  # FOG at rest first: its noise floor
harmonics: 3                         # once-per-rev harmonics fitted, orders 1..3
axes:
  main:
    rates_dps: [10, 50, 200]         # magnitudes; each runs +w then -w
tolerance:                           # what the table's maker claims, relative
  rate_error:
    - {below_dps: 10, rel: 1.0e-5}   # 0.001 % below 10 deg/s
    - {rel: 1.0e-6}                  # 0.0001 % from 10 deg/s
  rate_instability:
    - {rel: 1.0e-5}
specification:                       # where the tolerances above come from
  source: "TO FILL IN: the document they come from: maker, title, revision, date"
decision_rule: simple                # or guard-band
conditions: {temperature_c: "20 +/- 2"}
certificate:
  lab: lab.yaml                      # the laboratory's settings (below)
  customer: Example customer
"""

REAL_DRIVE = """\
      unit_factors: read             # read the drive's factor group at connect
      heartbeat_ms: 200              # the controller's heartbeat; the drive watches it
      watchdog_ms: 1500              # and stops the axis when it is silent this long
"""


def starter_files(real: bool) -> dict[str, str]:
    """File name -> text: the stand and the procedure."""
    if real:
        stand = STAND_HEAD.format(
            interface="socketcan", channel="can0",
            resource="TCPIP0::192.168.1.50::5025::SOCKET", port="/dev/ttyUSB0",
            drive_extra=REAL_DRIVE, mains_hint="", drive_hint="", counter_hint="",
            fog_hint="",
            # the numbers a real stand's budget rests on: its own calibrations'
            jitter='"TO FILL IN: the sensor\'s edge jitter, std, s (its certificate)"',
            timebase='"TO FILL IN: the reference\'s limit, relative (its certificate)"',
            latency='"TO FILL IN: the calibrated sync-to-trigger latency, s"',
            latency_u='"TO FILL IN: its standard uncertainty, s"')
        stand = ("# A real bench (no sim: block): check every address and limit.\n"
                 + HEAD.format(meanwhile="a real stand does not run until none is left.")
                 + stand)
    else:
        stand = STAND_HEAD.format(
            interface="virtual", channel="bench",
            resource="TCPIP0::127.0.0.1::5025::SOCKET", port="/dev/ttyUSB0",
            drive_extra=SIM_DRIVE, mains_hint=" (the twins' grid: 50)",
            drive_hint=f" (the twin reports {TWIN_DRIVE_SERIAL})",
            counter_hint=f" (the twin's: {TWIN_COUNTER_SERIAL})",
            fog_hint=" (the twin: KVH DSP-1760)",
            jitter="27.0e-9", timebase="1.0e-9", latency="2.0e-6", latency_u="2.0e-7",
        ) + SIM_BLOCK
        stand = ("# Runs on the simulated twins (the sim: block); for a real bench, "
                 "`bench init --real`.\n"
                 + HEAD.format(meanwhile="the twins run without it and the certificate "
                               "flags it\n# (NOT IDENTIFIED, NOT TRACEABLE), never printing "
                               "a placeholder as a value.")
                 + stand)
    return {"stand.yaml": stand, "procedure.yaml": PROCEDURE}
