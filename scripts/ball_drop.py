"""Drop a ball: impact time and numerical vs physical time (the README example)."""

import matplotlib.pyplot as plt

from tfcontact.fesd import simulate
from tfcontact.scenes.particles import point_mass
from tfcontact.timefreezing import time_freeze, to_physical_time

tf = time_freeze(point_mass(1, a_n=9.81))            # a ball 1 m above the ground, inelastic
res = simulate(tf.pss, tf.initial_state([1.0], [0.0]), horizon=1.5, n_steps=15,
               n_finite_elements=3)
phys = to_physical_time(tf, res.t, res.x)            # frozen pieces dropped, impacts as jumps
print("impact at t =", phys.impact_times)            # [0.4515...] = sqrt(2 h / g)
plt.plot(res.t, res.x[:, 1], label="v(tau), numerical time")
plt.plot(phys.t, phys.v[:, 0], label="v(t), physical time")
plt.xlabel("time [s]")
plt.legend()
plt.savefig("ball_drop.png")
