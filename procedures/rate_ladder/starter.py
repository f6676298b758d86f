"""The rate ladder's starter files for `bench init` (bench/app/starter.py): a commented
single-axis stand (drive, counter, FOG) and a procedure that validate; without --real
the stand runs on the twins (a `sim:` block), so `bench run DIR/procedure.yaml --yes`
works at once; --real leaves out `sim:` and writes the keys a real bench must state.
"""

from __future__ import annotations

STAND_HEAD = """\
# The stand: the rate table, its instruments and their limits (docs/configuration.md,
# `bench schema stand`). One file per bench; procedures name it with `stand:`.
stand:
  maker: Example Tables Ltd          # the table under test: maker, model, serial
  model: ET-1 single-axis rate table
  serial: "0001"                     # quoted: a serial is text, even when it is digits
  location: calibration room 1
axes:
  main:                              # your name for the axis; procedures use it
    drive:                           # the servo drive, CANopen CiA 402
      interface: {interface}               # python-can interface (socketcan, pcan, kvaser...)
      channel: {channel}                   # python-can channel
      node_id: 2
      max_rate_dps: 400              # the table's rate limit: no command exceeds it
      max_accel_dps2: 200            # its acceleration limit
      counts_per_rev: 1048576        # encoder counts per revolution
{drive_extra}\
    counter:                         # times the zero-mark pulses, one per turn
      resource: "{resource}"
      model: keysight-53230a         # counter profile: keysight-53230a, keysight-53220a...
      level_v: 2.5                   # absolute trigger level of the zero-mark pulse, V
      slope: POS
      trigger_jitter_s: 27.0e-9      # the zero-mark sensor's edge jitter, std
      reference: external            # timebase: set at connect and read back
      timebase_limit_rel: 1.0e-9     # the external 10 MHz reference's limit (its certificate)
      time_tie:                      # how the counter's start is placed on the FOG's time
        source: fog-sync             # FOG sync output -> counter EXT trigger
        sync_period_s: 5.0           # FOG time between sync pulses
        latency_s: 2.0e-6            # calibrated sync-to-trigger latency
        latency_u_s: 2.0e-7          # its standard uncertainty
    fog:                             # the reference gyro mounted on the table
      port: {port}
      baudrate: 921600
      format: kvh-a                  # KVH "format A" frames
      axis: z                        # the FOG axis along the table axis
      rate_hz: 1000                  # output rate
      range_dps: 490
      units: deg/s                   # what its rate fields carry (required)
      configure: set                 # set the units at connect and read them back
"""

SIM_DRIVE = """\
      heartbeat_ms: 200
      watchdog_ms: 1500
"""

SIM_BLOCK = """\
sim:                                 # the twins' truth; delete this block on a real bench
  seed: 1
  clock_speed: max                   # as fast as the twins keep up
  axes:
    main:
      rate_bias_rel: 3.0e-7          # mean table rate = set x (1 + this)
      harmonics:                     # once-per-rev rate ripple
        - {order: 1, amplitude_rel: 8.6e-4, phase_deg: 40}
      mains: {frequency_hz: 50, amplitude_dps: 2.0e-4, phase_deg: 0}
      rate_noise_dps: 1.0e-4
      turn_jitter_s: 27.0e-9
      fog: {scale: 1.0003, bias_dps: 0.002, misalignment_deg: 0.2,
            noise_dps: 0.01, bias_drift_dps_per_h: 0.001}
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
        stand = STAND_HEAD.format(interface="socketcan", channel="can0",
                                  resource="TCPIP0::192.168.1.50::5025::SOCKET",
                                  port="/dev/ttyUSB0", drive_extra=REAL_DRIVE)
        stand = "# A real bench (no sim: block): check every address and limit.\n" + stand
    else:
        stand = STAND_HEAD.format(interface="virtual", channel="bench",
                                  resource="TCPIP0::127.0.0.1::5025::SOCKET",
                                  port="/dev/ttyUSB0", drive_extra=SIM_DRIVE) + SIM_BLOCK
        stand = ("# Runs on the simulated twins (the sim: block); for a real bench, "
                 "`bench init --real`.\n" + stand)
    return {"stand.yaml": stand, "procedure.yaml": PROCEDURE}
