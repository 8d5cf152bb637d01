"""What a motion controller receives: the state estimate and the setpoint.

Both are defined once in :mod:`tapm_opt.interfaces` (with the protocols of the control loop) and
re-exported here. They do not validate shapes or finiteness: each controller checks its inputs
and raises its own typed error naming the bad field (a controller must never turn a NaN estimate
into a NaN command).
"""

from ..interfaces import Estimate, Setpoint

__all__ = ["Estimate", "Setpoint"]
