"""The slaves' fmi2GetFMUstate/SetFMUstate (models/slaves/state.py, QuickState) are pythonfmu's
own, made from lists built once: the same state dict, applied the same way."""
import pythonfmu
import pytest

from mecanum_fmu.models.slaves.dc_motor import DCMotor
from mecanum_fmu.models.slaves.odometry import Odometry
from mecanum_fmu.models.slaves.state import QuickState


@pytest.mark.parametrize("cls", [DCMotor, Odometry])
def test_the_state_is_pythonfmus_own_and_restores_every_value(cls, tmp_path):
    assert cls.__mro__.index(QuickState) < cls.__mro__.index(pythonfmu.Fmi2Slave)
    slave = cls(instance_name="s", resources=str(tmp_path))
    slave.enter_initialization_mode()
    slave.exit_initialization_mode()
    slave.set_real([slave.vars[0].value_reference], [3.0])     # the first input
    saved = slave._get_fmu_state()
    # pythonfmu's own (the class's own additions, Odometry's hidden state, on top)
    plain = pythonfmu.Fmi2Slave._get_fmu_state(slave)
    assert {k: saved[k] for k in plain} == plain and set(plain) == {v.name for v in
                                                                    slave.vars.values()}
    for _ in range(30):
        slave.do_step(0.0, 0.01)
    assert slave._get_fmu_state() != saved                   # the steps changed the state
    slave._set_fmu_state(saved)
    assert slave._get_fmu_state() == saved


def test_a_name_that_is_no_variable_is_set_as_an_attribute_and_a_setterless_one_skipped(tmp_path):
    """The same state applied to two motors, by QuickState and by pythonfmu's own: the same
    attributes after (a hidden name set, a variable without a setter left alone)."""
    motors = []
    for restore in (QuickState._set_fmu_state, pythonfmu.Fmi2Slave._set_fmu_state):
        slave = DCMotor(instance_name="s", resources=str(tmp_path))
        slave.enter_initialization_mode()
        state = {**slave._get_fmu_state(), "_hidden": 7.0, "V": -1.0, "w": 2.5}
        next(v for v in slave.vars.values() if v.name == "V").setter = None   # as a constant
        restore(slave, state)
        motors.append(slave)
    quick, plain = motors
    assert (quick._hidden, quick.V, quick.w) == (7.0, plain.V, 2.5) and quick.V != -1.0
    assert {v.name: getattr(quick, v.name) for v in quick.vars.values()} == \
        {v.name: getattr(plain, v.name) for v in plain.vars.values()}
