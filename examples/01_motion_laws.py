"""01: the motion laws and their characteristic values (peak velocity, acceleration and jerk of
a unit rise), and one law evaluated with its derivatives."""

import numpy as np

import ecam

for name in ("cycloidal", "modified_sine", "poly345"):
    law = ecam.law(name)
    print(f"{name:15s} Cv {law.cv:.4f}  Ca {law.ca:.4f}  Cj {law.cj:.4f}")

u = np.linspace(0.0, 1.0, 5)
cycloidal = ecam.law("cycloidal")
print("s(u)  ", np.round(cycloidal(u), 4))
print("s'(u) ", np.round(cycloidal(u, 1), 4))  # order 1: velocity of a unit rise over a unit span
