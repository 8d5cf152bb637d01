"""The reference of tests/test_semi_roll_pitch.py::test_option_off_plant_is_unchanged_bit_for_bit: ren8 and fpso
(seed 3, 6 segments) under a fixed thrust of 0.2 MN per thruster for 20 s, the plant rows and the
measurements, made with the plant before the low-frequency roll and pitch existed
(``python tests/data/make_plant_reference.py tests/data/plant_reference_option_off.npz``)."""
import sys, numpy as np
from tapm_opt.config import load_scenario
from tapm_opt.plant.simulator import Plant, run_open_loop
from tapm_opt.interfaces import ThrusterCommand

out = {}
for name, ss in (("ren8", "table3_vv9"), ("fpso", "storm")):
    sc = load_scenario(name)
    p = Plant(sc, sea_state=ss, seed=3, segments=6)
    n = p.thrusters.n
    cmd = ThrusterCommand(np.full(n, 2.0e5), p.thrusters.alpha.copy())
    rows = [p.sample_row()]
    meas = []
    for k in range(20):
        p.step(1.0, cmd)
        rows.append(p.sample_row())
        m = p.measure()
        meas.append(np.concatenate([m.position, [m.heading], m.tensions]))
    out[name + "_rows"] = np.array(rows)
    out[name + "_meas"] = np.array(meas)
np.savez(sys.argv[1], **out)
