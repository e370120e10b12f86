import pytest

from plem.fieldbus.bus import DriveState
from plem.fieldbus.cia402 import (
    ERROR_CODES,
    STATUSWORD,
    STATUSWORD_BITS,
    Controlword,
    decode_statusword,
    describe_drive_fault,
    describe_error_code,
    describe_statusword,
    drive_transition,
    next_controlword,
)

S = DriveState


@pytest.mark.parametrize("word, state", [
    (0x0000, S.NOT_READY_TO_SWITCH_ON), (0x0040, S.SWITCH_ON_DISABLED), (0x0021, S.READY_TO_SWITCH_ON),
    (0x0023, S.SWITCHED_ON), (0x0027, S.OPERATION_ENABLED), (0x0007, S.QUICK_STOP_ACTIVE),
    (0x000F, S.FAULT_REACTION_ACTIVE), (0x0008, S.FAULT),
    # bits outside the masks do not matter
    (0xFF90, S.NOT_READY_TO_SWITCH_ON), (0xFFF0, S.SWITCH_ON_DISABLED), (0xFFB1, S.READY_TO_SWITCH_ON),
    (0x1637, S.OPERATION_ENABLED), (0x2617, S.QUICK_STOP_ACTIVE), (0x003F, S.FAULT_REACTION_ACTIVE),
    (0x0238, S.FAULT),
])
def test_decode_statusword_follows_the_profile_table(word, state):
    assert decode_statusword(word) is state


@pytest.mark.parametrize("state", list(DriveState))
def test_canonical_statusword_decodes_to_its_state(state):
    word = STATUSWORD[state]
    assert decode_statusword(word) is state
    assert word & 0x0200, "a drive under fieldbus control reports remote"


@pytest.mark.parametrize("word, state", [(0x0001, S.NOT_READY_TO_SWITCH_ON), (0x0048, S.FAULT),
                                          (0x0067, S.NOT_READY_TO_SWITCH_ON)])
def test_words_outside_the_table_never_read_as_enabled(word, state):
    assert decode_statusword(word) is state


def test_describe_statusword_names_the_set_bits():
    assert describe_statusword(STATUSWORD[S.OPERATION_ENABLED]) == (
        "ready to switch on, switched on, operation enabled, voltage enabled, quick stop not active, remote")
    assert describe_statusword(0x2000) == "following error"
    assert describe_statusword(0x0C80) == "warning, target reached, internal limit active"
    assert describe_statusword(0) == "no bits set"
    assert len(STATUSWORD_BITS) == 16


def test_controlword_values_are_the_profile_commands():
    assert (Controlword.SHUTDOWN, Controlword.SWITCH_ON, Controlword.ENABLE_OPERATION) == (0x06, 0x07, 0x0F)
    assert (Controlword.DISABLE_VOLTAGE, Controlword.QUICK_STOP, Controlword.FAULT_RESET) == (0x00, 0x02, 0x80)


def test_enable_sequence_takes_three_commands():
    state, sent = S.SWITCH_ON_DISABLED, []
    while state is not S.OPERATION_ENABLED:
        command = next_controlword(state, S.OPERATION_ENABLED)
        sent.append(command)
        state = drive_transition(state, command, sent[-2] if len(sent) > 1 else 0)
    assert sent == [0x06, 0x07, 0x0F]
    assert next_controlword(state, S.OPERATION_ENABLED) == 0x0F


@pytest.mark.parametrize("start", list(DriveState))
@pytest.mark.parametrize("target", [S.OPERATION_ENABLED, S.SWITCH_ON_DISABLED, S.READY_TO_SWITCH_ON,
                                    S.SWITCHED_ON])
def test_sequencing_reaches_any_holdable_target_from_any_state(start, target):
    state, previous = start, 0x80
    for _ in range(8):
        command = next_controlword(state, target, previous)
        state, previous = drive_transition(state, command, previous), command
        if state is target:
            break
    assert state is target
    assert drive_transition(state, next_controlword(state, target, previous), previous) is target


def test_going_down_is_one_command():
    assert next_controlword(S.OPERATION_ENABLED, S.SWITCH_ON_DISABLED) == Controlword.DISABLE_VOLTAGE
    assert next_controlword(S.OPERATION_ENABLED, S.SWITCHED_ON) == Controlword.DISABLE_OPERATION
    assert next_controlword(S.OPERATION_ENABLED, S.READY_TO_SWITCH_ON) == Controlword.SHUTDOWN
    assert next_controlword(S.QUICK_STOP_ACTIVE, S.OPERATION_ENABLED) == Controlword.DISABLE_VOLTAGE


def test_fault_reset_needs_a_rising_edge():
    assert next_controlword(S.FAULT, S.OPERATION_ENABLED, previous=0x00) == Controlword.FAULT_RESET
    assert next_controlword(S.FAULT, S.OPERATION_ENABLED, previous=0x80) == Controlword.DISABLE_VOLTAGE
    assert drive_transition(S.FAULT, 0x80, previous=0x00) is S.SWITCH_ON_DISABLED
    assert drive_transition(S.FAULT, 0x80, previous=0x80) is S.FAULT
    assert drive_transition(S.FAULT, 0x0F, previous=0x00) is S.FAULT


def test_drive_side_transitions():
    assert drive_transition(S.NOT_READY_TO_SWITCH_ON, 0x00, 0) is S.SWITCH_ON_DISABLED
    assert drive_transition(S.FAULT_REACTION_ACTIVE, 0x0F, 0) is S.FAULT
    assert drive_transition(S.OPERATION_ENABLED, Controlword.QUICK_STOP, 0x0F) is S.QUICK_STOP_ACTIVE
    assert drive_transition(S.SWITCHED_ON, Controlword.QUICK_STOP, 0x07) is S.SWITCH_ON_DISABLED
    assert drive_transition(S.QUICK_STOP_ACTIVE, Controlword.ENABLE_OPERATION, 0x02) is S.OPERATION_ENABLED
    assert drive_transition(S.SWITCH_ON_DISABLED, Controlword.ENABLE_OPERATION, 0) is S.SWITCH_ON_DISABLED
    assert drive_transition(S.READY_TO_SWITCH_ON, Controlword.ENABLE_OPERATION, 0x06) is S.SWITCHED_ON
    for state in (S.READY_TO_SWITCH_ON, S.SWITCHED_ON, S.OPERATION_ENABLED, S.QUICK_STOP_ACTIVE):
        assert drive_transition(state, Controlword.DISABLE_VOLTAGE, 0x0F) is S.SWITCH_ON_DISABLED


def test_next_controlword_rejects_a_target_it_cannot_hold():
    with pytest.raises(ValueError, match="FAULT"):
        next_controlword(S.SWITCH_ON_DISABLED, S.FAULT)


@pytest.mark.parametrize("code, text", [
    (0x0000, "0x0000 no error"),
    (0x8611, "0x8611 following error"),
    (0x7121, "0x7121 motor blocked"),
    (0x2310, "0x2310 continuous over current"),
    (0x3210, "0x3210 DC link over voltage"),
    (0x8130, "0x8130 heartbeat or life guard error"),
    (0x7305, "0x7305 incremental encoder 1 broken"),
    (0x2399, "0x2399 current, device output side (0x23xx)"),
    (0x4399, "0x4399 drive temperature (0x43xx)"),
    (0x2500, "0x2500 current (0x2xxx)"),
    (0xFF12, "0xFF12 manufacturer-specific"),
    (0xB000, "0xB000 unknown error code"),
])
def test_describe_error_code(code, text):
    assert describe_error_code(code) == text


def test_error_table_is_sizeable_and_well_formed():
    assert len(ERROR_CODES) >= 40
    assert all(0 <= code <= 0xFFFF and text for code, text in ERROR_CODES.items())


def test_describe_drive_fault_is_one_line():
    line = describe_drive_fault("joint2", STATUSWORD[S.FAULT], 0x7121)
    assert line == "joint2 drive fault: 0x7121 motor blocked (statusword 0x0218: fault, voltage enabled, remote)"
    assert "\n" not in line
