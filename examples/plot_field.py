"""Plot the first field of an `ebiv process ... -o flow.csv` output as a vector map.

    python examples/plot_field.py flow.csv flow.png     (needs numpy and matplotlib)
"""
import sys
import numpy as np
import matplotlib
matplotlib.use("Agg")
import matplotlib.pyplot as plt

source = sys.argv[1] if len(sys.argv) > 1 else "flow.csv"
target = sys.argv[2] if len(sys.argv) > 2 else "flow.png"
f = np.genfromtxt(source, delimiter=",", names=True, comments="#")
# The first field's valid vectors (invalid ones are NaN); column names carry the units.
ok = (f["status"] == 0) & (f["t_us"] == f["t_us"][0])
x, y, u, v = (f[k][ok] for k in ("x_px", "y_px", "u_px_ms", "v_px_ms"))
# angles="xy": arrows in data coordinates, so that v > 0 (down in the image) points down
# once the y axis is inverted.
plt.quiver(x, y, u, v, np.hypot(u, v), angles="xy")
plt.gca().invert_yaxis()                    # image coordinates: y down
plt.xlabel("x (px)")
plt.ylabel("y (px)")
plt.title(f"{source}: first field")
plt.gca().set_aspect("equal")
plt.colorbar(label="|v| (px/ms)")
plt.savefig(target, dpi=150)
print(f"wrote {target}: {ok.sum()} valid vectors")
