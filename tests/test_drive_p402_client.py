"""The drive twin against an independent CiA 402 client: canopen's own BaseNode402
(canopen/profiles/p402.py), driving it over a python-can bus exactly as it drives a drive.

Each test is one disagreement of issue 24 (the twin accepted, ignored or answered what a
CiA 402/301 drive does not). Sources for what a drive does:
- CiA 402-2 (IEC 61800-7-201) option codes 0x605A-0x605E and 0x6007 as restated in the
  Nanotec PD4-E technical manual (object descriptions 6007h, 605Ah-605Eh) and the
  Synapticon SOMANET object reference: 0x605A 0-8 (5-8 stay in quick stop active, the
  only codes with transition 16), 0x605D halt 1-4, 0x605E 0-4, 0x6007 0-3; other values
  reserved, refused with SDO abort 0x06090030 (CiA 301 value range exceeded).
- CiA 301 7.3.2 (NMT): a reset ends in a boot-up message and pre-operational; no SDO
  in Stopped; 7.5.2.35-38 PDO parameters: COB-ID bit 31 "not valid", transmission types
  1-240 on SYNC, a mapping changed only while the PDO is not valid.

Issue 41 (the same sources):
- CiA 301 7.2.2.3 / 0x1400 sub 2: the data of a synchronous RPDO (types 0-240) are
  actuated at the next SYNC, of an asynchronous one (254/255) at once (canopen's own
  PdoMap.is_periodic says "RPDOs need a SYNC to apply"; Lely's rpdo.c keeps the frame
  "to be processed after the next SYNC object"). The twin applied them at once.
- CiA 301 7.5.2.36/38, the mapping procedure: bit 31 set, sub-index 0 to 0, the entries,
  sub-index 0 to their count, bit 31 cleared. Sub-index 0 written while the PDO was
  valid was accepted; now 0x08000022 as for the entries (CiA 301's text was not at
  hand; CANopenNode answers 0x06010000, Lely 0x06090030: see sims/drive_twin.py).
- An entry must map its object at the object's length (0x6041, 16 bits, as 32 was
  accepted): abort 0x06040041 "object cannot be mapped to the PDO" (7.5.2.36 step 3).
- CiA 402 0x6091: after a ratio the twin refused with a general error 0x08000000, 1:1
  was refused too until Reset Node; every step is now consistent.
"""

from __future__ import annotations

import time
from collections.abc import Iterator
from typing import Any

import canopen
import pytest
from canopen.profiles.p402 import BaseNode402
from canopen.sdo import SdoAbortedError, SdoCommunicationError

from drivers.cia402 import DEFAULT_EDS_PATH, Od, State
from sims.clock import VirtualClock
from sims.drive_twin import DriveTwin
from tests.conftest import Twins, one_axis_stand
from tests.test_axis import wait_until as wait_for

pytestmark = pytest.mark.timeout(60)

NODE = 2
#: the twin's velocity unit: 0.001 increments/s, 2^20 increments a turn
VEL_UNITS_PER_DPS = 1000 * 2**20 / 360.0


class Client:
    """A user's script: canopen Network + BaseNode402 on the twin's bus."""

    def __init__(self, twin: DriveTwin) -> None:
        self.twin = twin
        self.network = canopen.Network()
        self.network.connect(interface="virtual", channel=twin.channel)
        self.node = BaseNode402(NODE, str(DEFAULT_EDS_PATH))
        self.network.add_node(self.node)
        self.node.sdo.RESPONSE_TIMEOUT = 1.0
        self.node.tpdo.read()
        self.node.rpdo.read()
        self.node.setup_402_state_machine(read_pdos=False)
        self.node.nmt.state = "OPERATIONAL"
        wait_for(lambda: twin._node.nmt.state == "OPERATIONAL", 2.0)

    def close(self) -> None:
        self.network.disconnect()


@pytest.fixture
def twin(twins: Twins) -> DriveTwin:
    return twins.drive(one_axis_stand(VirtualClock(20.0)), node_id=NODE)


@pytest.fixture
def client(twin: DriveTwin) -> Iterator[Client]:
    c = Client(twin)
    try:
        yield c
    finally:
        c.close()


def turning(c: Client, rate_dps: float) -> None:
    c.node.op_mode = "PROFILED VELOCITY"
    c.node.sdo[0x60FF].raw = 0
    c.node.state = "OPERATION ENABLED"
    c.node.sdo[0x60FF].raw = round(rate_dps * VEL_UNITS_PER_DPS)
    assert wait_for(lambda: abs(c.twin.model.rate_dps) > 0.5 * abs(rate_dps), 10.0)


def test_every_controller_transition_through_base_node_402(client: Client) -> None:
    n, twin = client.node, client.twin
    for target in ("READY TO SWITCH ON", "SWITCHED ON", "OPERATION ENABLED",  # 2, 3, 4
                   "SWITCHED ON", "READY TO SWITCH ON", "SWITCH ON DISABLED",  # 5, 6, 7
                   "READY TO SWITCH ON", "SWITCHED ON", "SWITCH ON DISABLED",  # 2, 3, 10
                   "READY TO SWITCH ON", "SWITCHED ON", "OPERATION ENABLED",
                   "READY TO SWITCH ON",                                        # 8
                   "SWITCHED ON", "OPERATION ENABLED", "SWITCH ON DISABLED"):   # 9
        n.state = target
        assert n.state == target
    # the controlword went by RPDO1 (0x200 + node), as the EDS now declares
    assert 0x6040 in n.rpdo_pointers
    # fault and fault reset (13, 14, 15)
    n.state = "OPERATION ENABLED"
    twin.inject(0x4310)
    assert wait_for(lambda: n.is_faulted(), 5.0)
    n.reset_from_fault()             # canopen's: 0x80 (15), then on to operation enabled
    assert n.state == "OPERATION ENABLED" and twin.fault is None


def test_transition_16_only_with_quick_stop_codes_5_to_8(client: Client) -> None:
    n, twin = client.node, client.twin
    # code 2 (the EDS default): quick stop ends in Switch on disabled; 16 is refused
    turning(client, 30.0)
    n.controlword = 0x02  # quick stop (11)
    assert wait_for(lambda: twin.state is State.QUICK_STOP_ACTIVE, 2.0)
    n.controlword = 0x0F  # enable operation: no transition 16 with 0x605A = 2
    time.sleep(0.1)
    assert twin.state is not State.OPERATION_ENABLED
    assert wait_for(lambda: twin.state is State.SWITCH_ON_DISABLED, 10.0)
    # code 6: it stays in quick stop active at rest, and 16 re-enables
    n.sdo[0x605A].raw = 6
    turning(client, 30.0)
    n.controlword = 0x02
    assert wait_for(lambda: twin.state is State.QUICK_STOP_ACTIVE, 2.0)
    assert wait_for(lambda: twin.model.rate_dps == 0.0, 10.0)
    time.sleep(0.1)
    assert twin.state is State.QUICK_STOP_ACTIVE
    n.controlword = 0x0F
    assert wait_for(lambda: twin.state is State.OPERATION_ENABLED, 2.0)


@pytest.mark.parametrize("index, bad", [(0x6007, 9), (0x6007, -1), (0x605A, 9),
                                        (0x605A, -3), (0x605B, 2), (0x605C, 5),
                                        (0x605D, 0), (0x605D, 5), (0x605E, 5)])
def test_reserved_option_codes_are_refused_with_value_range(client: Client, index: int,
                                                           bad: int) -> None:
    before = client.node.sdo[index].raw
    with pytest.raises(SdoAbortedError) as e:
        client.node.sdo[index].raw = bad
    assert e.value.code == 0x06090030
    assert client.node.sdo[index].raw == before


@pytest.mark.parametrize("code, decel_object", [(2, Od.QUICK_STOP_DECELERATION),
                                                (3, Od.MAX_DECELERATION),
                                                (7, Od.MAX_DECELERATION),
                                                (1, Od.PROFILE_DECELERATION)])
def test_quick_stop_codes_use_their_own_ramp(client: Client, code: int,
                                             decel_object: Od) -> None:
    n, twin = client.node, client.twin
    n.sdo[0x605A].raw = code
    turning(client, 30.0)
    n.controlword = 0x02
    assert wait_for(lambda: twin.model.commanded_rate_at(twin.clock.now()) == 0.0, 2.0)
    seg = twin.model.profile.segments[-1]
    assert seg.target_dps == 0.0
    expected = twin.units.accel_to_dps2(n.sdo[decel_object].raw)
    assert seg.accel_dps2 == \
        pytest.approx(expected, rel=1e-9)
    end = State.QUICK_STOP_ACTIVE if code >= 5 else State.SWITCH_ON_DISABLED
    assert wait_for(lambda: twin.state is end and twin.model.rate_dps == 0.0, 10.0)


def test_halt_bit_stops_with_0x605D_and_resumes(client: Client) -> None:
    n, twin = client.node, client.twin
    assert n.sdo[0x605D].raw == 1  # declared in the EDS
    n.sdo[0x605D].raw = 2          # quick stop ramp
    turning(client, 20.0)
    n.controlword = 0x010F         # halt
    assert wait_for(lambda: twin.model.rate_dps == 0.0, 10.0)
    assert twin.state is State.OPERATION_ENABLED
    seg = twin.model.profile.segments[-1]
    assert seg.target_dps == 0.0
    # PV statusword bit 10 with halt set: the axis has stopped
    assert wait_for(lambda: n.sdo[0x6041].raw & (1 << 10), 5.0)
    n.controlword = 0x000F         # halt released: back to 0x60FF
    assert wait_for(lambda: abs(twin.model.rate_dps - 20.0) < 0.5, 10.0)


def test_nmt_stopped_takes_the_abort_connection_reaction_and_no_sdo(client: Client) -> None:
    n, twin = client.node, client.twin
    n.sdo[0x6007].raw = 3          # quick stop
    turning(client, 30.0)
    n.nmt.state = "STOPPED"
    assert wait_for(lambda: twin.state is not State.OPERATION_ENABLED, 2.0)
    assert wait_for(lambda: twin.model.rate_dps == 0.0, 10.0)
    n.sdo.RESPONSE_TIMEOUT = 0.3
    with pytest.raises(SdoCommunicationError):
        _ = n.sdo[0x6041].raw      # CiA 301: no SDO in Stopped
    n.nmt.state = "PRE-OPERATIONAL"
    assert n.sdo[0x6041].raw


@pytest.mark.parametrize("command", ["RESET", "RESET COMMUNICATION"])
def test_a_remote_reset_boots_up_again(client: Client, command: str) -> None:
    n, twin = client.node, client.twin
    n.sdo[0x1017].raw = 50
    n.sdo[0x605A].raw = 6
    turning(client, 30.0)
    n.nmt.state = command
    n.nmt.wait_for_bootup(5.0)     # the boot-up message (0x700 + node, data 0)
    n.nmt.wait_for_heartbeat(2.0)
    assert n.nmt.state == "PRE-OPERATIONAL"
    assert wait_for(lambda: twin.model.rate_dps == 0.0, 10.0)  # 0x6007 = 1: fault reaction
    assert n.sdo[0x1017].raw == 100  # the communication area is back to its defaults
    if command == "RESET":           # and with reset node the application area too
        assert n.sdo[0x605A].raw == 2
        assert wait_for(lambda: twin.state is State.SWITCH_ON_DISABLED, 10.0)
    else:
        assert n.sdo[0x605A].raw == 6


def test_pdo_remap_disable_and_sync(client: Client) -> None:
    n, net = client.node, client.network
    seen: list[int] = []
    net.subscribe(0x280 + NODE, lambda can_id, data, ts: seen.append(can_id))
    # canopen's own PDO save: disable (bit 31), remap, transmission type 1, enable
    n.nmt.state = "PRE-OPERATIONAL"
    tpdo1 = n.tpdo[1]
    tpdo1.clear()
    tpdo1.add_variable(0x6041)
    tpdo1.add_variable(0x606C)
    tpdo1.trans_type = 1
    tpdo1.enabled = True
    tpdo1.save()
    n.tpdo[2].enabled = False
    n.tpdo[2].save()
    assert n.sdo[0x1801][1].raw & (1 << 31)
    n.nmt.state = "OPERATIONAL"
    time.sleep(0.1)
    seen.clear()
    got: list[bytes] = []
    net.subscribe(0x180 + NODE, lambda can_id, data, ts: got.append(bytes(data)))
    time.sleep(0.15)
    assert got == []               # synchronous now: nothing without SYNC
    net.sync.start(0.02)
    try:
        assert wait_for(lambda: len(got) >= 3, 3.0)
    finally:
        net.sync.stop()
    assert seen == []              # TPDO2 disabled: silent
    statusword = int.from_bytes(got[-1][:2], "little")
    assert len(got[-1]) == 6 and statusword & 0x4F == 0x40  # switch on disabled, new layout
    # a valid PDO's mapping is not changed behind its back (CiA 301)
    with pytest.raises(SdoAbortedError):
        n.sdo[0x1A00][1].raw = 0x60640020


def test_factor_group_writes_are_applied(client: Client) -> None:
    n, twin = client.node, client.twin
    n.sdo[0x608F][1].raw = 4096          # 4096 increments a motor turn
    # 409600 units of 0.001 inc/s = 409.6 inc/s = 0.1 turn/s = 36 deg/s
    n.op_mode = "PROFILED VELOCITY"
    n.sdo[0x60FF].raw = 0
    n.state = "OPERATION ENABLED"
    n.sdo[0x60FF].raw = 409600
    assert wait_for(lambda: abs(twin.model.rate_dps - 36.0) < 0.05, 10.0)
    with pytest.raises(SdoAbortedError) as e:  # not while the power stage is on
        n.sdo[0x6091][1].raw = 2
    assert e.value.code == 0x08000022
    n.sdo[0x60FF].raw = 0
    assert wait_for(lambda: twin.model.rate_dps == 0.0, 10.0)
    n.state = "SWITCH ON DISABLED"
    n.sdo[0x6091][1].raw = 2             # gear 2:1: the table turns at half
    n.sdo[0x6096][1].raw = 4             # velocity factor 4/1
    n.state = "OPERATION ENABLED"
    n.sdo[0x60FF].raw = 409600
    assert wait_for(lambda: abs(twin.model.rate_dps - 72.0) < 0.1, 10.0)


def test_eds_declares_what_the_twin_starts_with(client: Client) -> None:
    od = canopen.import_od(str(DEFAULT_EDS_PATH), NODE)
    assert client.node.sdo[0x1016][1].raw == od[0x1016][1].default == 0x007F00FA
    assert od[0x1400][1].default == 0x200 + NODE and od[0x1401][1].default == 0x300 + NODE
    assert [od[0x1600][k].default for k in (1, 2)] == [0x60400010, 0x60600008]
    # no text before the first section: CiA 306 keeps comments in [Comments]
    first = DEFAULT_EDS_PATH.read_text().lstrip().splitlines()[0]
    assert first == "[FileInfo]"


def test_an_independent_eds_checker_reads_the_eds_cleanly() -> None:
    """eds-utils (PyPI) reads EDS files section by section; the old leading comment
    block made it fail outright. Its only remark now is that [ManufacturerObjects] lists
    no object, which it reports as 'missing' (CiA 306 allows SupportedObjects=0)."""
    from eds_utils.core.file_io.read_eds import read_eds

    eds, errors = read_eds(str(DEFAULT_EDS_PATH))
    assert errors == ["AUTO-FIXED: Section [ManufacturerObjects] was missing"]
    od = canopen.import_od(str(DEFAULT_EDS_PATH), NODE)
    assert {0x1400, 0x1401, 0x1600, 0x1601, 0x605D, 0x1005} <= set(od.indices)


def _rpdo_controlword(pdo: Any) -> Any:
    return next(v for v in pdo.map if v.index == 0x6040)


def test_a_synchronous_rpdo_is_actuated_at_the_next_sync(client: Client) -> None:
    n, net, twin = client.node, client.network, client.twin
    rpdo1 = n.rpdo[1]                      # controlword and mode, as the EDS maps them
    n.nmt.state = "PRE-OPERATIONAL"        # canopen's own PDO save: type 1 (every SYNC)
    rpdo1.trans_type = 1
    rpdo1.save()
    assert n.sdo[0x1400][2].raw == 1
    n.nmt.state = "OPERATIONAL"
    assert wait_for(lambda: twin._node.nmt.state == "OPERATIONAL", 2.0)
    cw = _rpdo_controlword(rpdo1)
    cw.raw = 0x06                          # shutdown: transition 2
    rpdo1.transmit()
    time.sleep(0.3)
    assert twin.state is State.SWITCH_ON_DISABLED    # received, not actuated: no SYNC
    net.sync.transmit()
    assert wait_for(lambda: twin.state is State.READY_TO_SWITCH_ON, 2.0)
    # canopen's way with a synchronous RPDO: sent cyclically, a SYNC producer beside it,
    # and BaseNode402 drives the state machine through them
    rpdo1.start(0.02)
    net.sync.start(0.02)
    try:
        n.state = "OPERATION ENABLED"
        assert twin.state is State.OPERATION_ENABLED
        net.sync.stop()
        cw.raw = 0x07                      # disable operation: waits for the next SYNC
        time.sleep(0.3)
        assert twin.state is State.OPERATION_ENABLED
        net.sync.transmit()
        assert wait_for(lambda: twin.state is State.SWITCHED_ON, 2.0)
    finally:
        net.sync.stop()
        rpdo1.stop()
    # asynchronous again (255): actuated at once, no SYNC
    n.nmt.state = "PRE-OPERATIONAL"
    rpdo1.trans_type = 255
    rpdo1.save()
    n.nmt.state = "OPERATIONAL"
    assert wait_for(lambda: twin._node.nmt.state == "OPERATIONAL", 2.0)
    cw.raw = 0x06
    rpdo1.transmit()
    assert wait_for(lambda: twin.state is State.READY_TO_SWITCH_ON, 2.0)


@pytest.mark.parametrize("index", [0x1600, 0x1A00])
def test_a_valid_pdos_mapping_is_not_changed_not_even_its_count(client: Client,
                                                               index: int) -> None:
    n = client.node
    comm = index - 0x200
    count, first = n.sdo[index][0].raw, n.sdo[index][1].raw
    assert not n.sdo[comm][1].raw & (1 << 31)            # valid
    for sub, value in ((0, 0), (0, count), (1, first)):
        with pytest.raises(SdoAbortedError) as e:
            n.sdo[index][sub].raw = value
        assert e.value.code == 0x08000022
    assert (n.sdo[index][0].raw, n.sdo[index][1].raw) == (count, first)
    # not valid: the entries only once sub-index 0 is 0 (CiA 301's procedure)
    n.sdo[comm][1].raw = n.sdo[comm][1].raw | (1 << 31)
    with pytest.raises(SdoAbortedError) as e:
        n.sdo[index][1].raw = first
    assert e.value.code == 0x08000022
    n.sdo[index][0].raw = 0
    n.sdo[index][1].raw = first
    n.sdo[index][0].raw = count
    n.sdo[comm][1].raw = n.sdo[comm][1].raw & ~(1 << 31)
    # the public client's whole procedure goes through
    pdos = n.rpdo if index == 0x1600 else n.tpdo
    pdos[1].read()
    pdos[1].save()
    assert (n.sdo[index][0].raw, n.sdo[index][1].raw) == (count, first)


def test_a_mapping_entry_must_map_its_object_at_its_own_length(client: Client) -> None:
    n = client.node
    tpdo1 = n.tpdo[1]                      # canopen's API: 0x6041 (16 bits) as 32
    tpdo1.clear()
    tpdo1.add_variable(0x6041, length=32)
    tpdo1.enabled = True
    with pytest.raises(SdoAbortedError) as e:
        tpdo1.save()
    assert e.value.code == 0x06040041
    for entry in (0x60410020, 0x60410008, 0x606C0010, 0x60FF0040, 0x12340010, 0x10000020):
        with pytest.raises(SdoAbortedError) as e:  # wrong lengths; not mappable; absent
            n.sdo[0x1A00][1].raw = entry
        assert e.value.code == 0x06040041, hex(entry)
    n.sdo[0x1A00][1].raw = 0x60410010      # its own 16 bits
    n.sdo[0x1A00][2].raw = 0x606C0020      # 0x606C, INTEGER32
    n.sdo[0x1A00][0].raw = 2
    with pytest.raises(SdoAbortedError) as e:  # more entries than the PDO has
        n.sdo[0x1A00][0].raw = 0x40
    assert e.value.code == 0x06040042


@pytest.mark.parametrize("one_to_two, back", [
    ([(2, 2)], [(2, 1)]),                   # 0x6091 motor:shaft = 1:2, then 1:1
    ([(1, 2)], [(1, 1)]),                   # 2:1 (a "1:2" gear, shaft:motor)
    ([(2, 1), (1, 2)], [(2, 1), (1, 1)]),   # 2:1 written sub 2 first; back likewise
    ([(1, 1), (2, 2)], [(1, 1), (2, 1)]),
])
def test_gear_ratio_back_to_one_to_one_is_accepted(client: Client,
                                                   one_to_two: list[tuple[int, int]],
                                                   back: list[tuple[int, int]]) -> None:
    n, twin = client.node, client.twin
    window = n.sdo[0x606D].raw
    for sub, value in one_to_two + back:
        n.sdo[0x6091][sub].raw = value       # every step answered, none refused
        f = twin.factors                     # and the twin's units are the OD's
        assert (f.gear_motor_revs, f.gear_shaft_revs) == (n.sdo[0x6091][1].raw,
                                                          n.sdo[0x6091][2].raw)
    assert (n.sdo[0x6091][1].raw, n.sdo[0x6091][2].raw) == (1, 1)
    assert n.sdo[0x606D].raw == window       # its deg/s as at the start
    # and the drive turns in its units as before: 36 deg/s
    n.op_mode = "PROFILED VELOCITY"
    n.sdo[0x60FF].raw = 0
    n.state = "OPERATION ENABLED"
    n.sdo[0x60FF].raw = round(36.0 * VEL_UNITS_PER_DPS)
    assert wait_for(lambda: abs(twin.model.rate_dps - 36.0) < 0.05, 10.0)


def test_a_gear_ratio_the_limits_cannot_follow_saturates_them(client: Client) -> None:
    """At 2:1 the velocity window's 0.02 deg/s is 116 508 units of 0.001 inc/s, more than
    0x606D (UNSIGNED16) holds: the ratio is taken (it was a general error 0x08000000),
    the window holds its largest value, and 1:1 gives it back."""
    n = client.node
    window = n.sdo[0x606D].raw
    n.sdo[0x6091][1].raw = 2
    assert n.sdo[0x606D].raw == 0xFFFF
    n.sdo[0x6091][1].raw = 1
    assert n.sdo[0x606D].raw == window
