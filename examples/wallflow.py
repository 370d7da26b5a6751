"""Velocity field of a real wall flow, from the event recording to a figure, in Python.

    python examples/wallflow.py [wallflow_slice2.npz] [wallflow.png]

The recording is the shared test data's `ebiv/wallflow_slice2.npz`: 20 ms of positive events
of a 512x512 px slice of the EBIV paper's water flow along a wall (found through
$EBIV_TEST_DATA, else ../shared/data beside the repository). Needs the package with xarray
and matplotlib: pip install "./crates/ebiv-py[xarray]" matplotlib
"""
import os
import pathlib
import sys

import matplotlib
import numpy as np

headless = not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))
if sys.platform.startswith("linux") and headless:
    matplotlib.use("Agg")  # no display: draw into the file only
import matplotlib.pyplot as plt

import ebiv

repository = pathlib.Path(__file__).resolve().parents[1]
data = os.environ.get("EBIV_TEST_DATA") or repository.parent / "shared" / "data"
source = sys.argv[1] if len(sys.argv) > 1 else os.path.join(data, "ebiv", "wallflow_slice2.npz")
target = sys.argv[2] if len(sys.argv) > 2 else "wallflow.png"

# 1. What the file holds. NumPy files do not store the sensor size: the slice is 512x512 px.
geometry = (512, 512)
rec = ebiv.open(source, geometry=geometry)
first, last = rec.time_range  # µs of camera time
print(f"{rec.path}: {rec.metadata['format']}, {rec.geometry[0]}x{rec.geometry[1]} px")
print(f"{rec.report['events']} events from {first} to {last} µs ({(last - first) / 1000:.1f} ms)")

# 2. Velocity fields by sum of correlation at the EBIV paper's settings (also the defaults):
# positive events, slab T = 10 ms, delay tau = 3 ms, passes of 64 then 40 px windows at 50 %
# overlap. A field needs T + tau = 13 ms of events, so the 20 ms slice holds fields centred
# between 6.5 and 13.5 ms after the first event; time="::2ms" asks for one every 2 ms.
# decode_times=False keeps the field times in µs of camera time, as the events have them.
ds = ebiv.process(source, method="corrsum", geometry=geometry, polarity="pos", slab="10ms",
                  tau="3ms", window=[64, 40], time="::2ms", decode_times=False)
print(ds)  # the dataset: u, v in px/ms, their uncertainty, status flags, peak ratio, …
valid = ds.status == 0  # invalid vectors are NaN in u and v, with their reasons in status
print(f"{ds.sizes['time']} fields, {float(valid.mean()):.1%} of the vectors valid")

# 3. The events of the first field's slab, as an image: events per pixel.
field = ds.isel(time=0)
t_c, slab = int(field.time), int(field.slab_us.max())
ev = rec.read(t_c - slab // 2, t_c + slab // 2)
image, _, _ = np.histogram2d(ev.y, ev.x, bins=(geometry[1], geometry[0]),
                             range=((0, geometry[1]), (0, geometry[0])))

fig, (left, right) = plt.subplots(1, 2, figsize=(11, 5), gridspec_kw={"width_ratios": [3, 1.3]})
# Image coordinates: pixel centres at integers, y pointing down (origin="upper").
left.imshow(image, cmap="Greys", vmax=1.5 * np.percentile(image[image > 0], 99),
            extent=(-0.5, geometry[0] - 0.5, geometry[1] - 0.5, -0.5))
x, y = np.meshgrid(field.x, field.y)
speed = np.hypot(field.u, field.v)
# angles="xy": arrows in data coordinates, so v > 0 points down the inverted y axis; each arrow
# is the displacement over 5 ms (scale=0.2: 0.2 px/ms per px of arrow).
arrows = left.quiver(x, y, field.u, field.v, speed, angles="xy", scale_units="xy", scale=0.2,
                     width=0.004, cmap="plasma")
fig.colorbar(arrows, ax=left, label="|v| (px/ms)")
when = (t_c - first) / 1000  # ms after the first event
left.set(xlabel="x (px)", ylabel="y (px)",
         title=f"events of the {slab / 1000:g} ms slab at {when:g} ms, corrsum field")

# 4. The mean streamwise velocity over y: averaged over x and the fields, valid vectors only.
# The fields' slabs overlap, so the average is not over independent samples.
u_mean = ds.u.mean(dim=("time", "x"))
u_std = ds.u.std(dim=("time", "x"))
right.plot(u_mean, ds.y, "k.-")
right.fill_betweenx(ds.y, u_mean - u_std, u_mean + u_std, color="0.8", label="±1 std over x, t")
right.set(xlabel="u (px/ms)", ylabel="y (px)", ylim=(geometry[1], 0), title="time-averaged u")
right.legend(loc="upper left")
right.grid(alpha=0.3)

fig.tight_layout()
fig.savefig(target, dpi=120)
print(f"wrote {target}")
if matplotlib.get_backend().lower() != "agg":
    plt.show()
