"""Writes the HDF5 test recordings of `tests/hdf5.rs` next to this script.

    python make_fixtures.py        # needs numpy and h5py

or writes any recording as a Metavision HDF5 file with ECF-compressed chunks of 16 384 events,
each in its smallest coordinate layout (for `ebiv bench decode`):

    ebiv convert REC events.npz
    python make_fixtures.py --from events.npz --geometry 1280x720 -o REC.hdf5

Each file comes with `<name>.expected.npz`: the events it holds (columns t, x, y, p) in file
order, which the Rust tests compare with what ebiv decodes.

- `metavision_ecf.hdf5`: Metavision's layout. `/CD/events` is chunked (1000 events per chunk,
  the last chunk partial) and its chunks are compressed with the ECF codec by the encoder
  below, written from the codec's published layout (formats.md §6.3) independently of ebiv's
  own, and stored with h5py's direct chunk write under filter id 0x8ECF. The chunks cycle
  through the three coordinate layouts; the events include time steps from 0 to 2^40 µs,
  runs of equal time stamps and rows longer than the 15 and 31 escapes, and polarity runs
  longer than 127. Also `/CD/indexes` (2000 µs bins), `/EXT_TRIGGER/events` and the root
  attributes `geometry` and `time_shift`.
- `metavision_plain.hdf5`: the same layout with `/CD/events` stored without a filter.
- `dsec_columns.h5`: DSEC's layout: `events/{x,y,t,p}`, `t_offset` and `ms_to_idx`.
"""

import pathlib
import struct

import h5py
import numpy as np

HERE = pathlib.Path(__file__).resolve().parent
ECF = 0x8ECF
CD = np.dtype({"names": ["x", "y", "p", "t"], "formats": ["<u2", "<u2", "<i2", "<i8"],
               "offsets": [0, 2, 4, 8], "itemsize": 16})
TRIGGER = np.dtype({"names": ["p", "t", "id"], "formats": ["<i2", "<i8", "<i2"],
                    "offsets": [0, 8, 16], "itemsize": 24})
INDEX = np.dtype([("id", "<u8"), ("ts", "<i8")])


def runs(values):
    """(value, length) of each run of equal values."""
    out = []
    for v in values:
        if out and out[-1][0] == v:
            out[-1][1] += 1
        else:
            out.append([v, 1])
    return out


def ecf_encode(x, y, p, t, layout):
    """One ECF buffer; layout 0: masked x, 1: x and p packed, 2: all packed."""
    n = len(t)
    out = bytearray(struct.pack("<I", n << 2 | (2 if layout == 2 else 0) | (1 if layout == 1 else 0)))
    out += struct.pack("<Q", int(t[0]) if n else 0)
    now = int(t[0]) if n else 0
    for value, length in runs([int(v) for v in t]):
        step = value - now
        assert step >= 0, "the fixtures' times rise"
        if step >= 15:
            while step:
                out.append(0xF0 | (step & 0xF))
                step >>= 4
        now = value
        if length >= 15:
            out += bytes([step << 4 | 0xF]) + struct.pack("<H", length)
        else:
            out.append(step << 4 | length)
    if layout == 2:
        vals = [(int(y[i]) << 12 | int(x[i]) << 1 | int(p[i])) for i in range(n)]
        vals += [0] * (-n % 4)
        for k in range(0, len(vals), 4):
            a, b, c, d = vals[k:k + 4]
            out += struct.pack("<III", a << 8 | (b & 0xFF), (b >> 8) << 16 | (c & 0xFFFF),
                               (c >> 16) << 24 | (d & 0xFFFFFF))
        return bytes(out)
    for value, length in runs([int(v) for v in y]):
        if length >= 31:
            out += struct.pack("<HH", value << 5 | 31, length)
        else:
            out += struct.pack("<H", value << 5 | length)
    if layout == 1:
        vals = [(int(x[i]) << 1 | int(p[i])) for i in range(n)] + [0] * (-n % 4)
        for k in range(0, len(vals), 4):
            a, b, c, d = vals[k:k + 4]
            out += struct.pack("<HHH", (a << 4 | (b & 0xF)) & 0xFFFF,
                               ((b >> 4) << 8 | (c & 0xFF)) & 0xFFFF,
                               ((c >> 8) << 12 | (d & 0xFFF)) & 0xFFFF)
        return bytes(out)
    i = 0
    while i < n:
        base, word = int(x[i]), int(x[i]) << 5
        i += 1
        for j in range(5):
            if i < n and int(x[i]) == base + j + 1:
                word |= 1 << (4 - j)
                i += 1
        out += struct.pack("<H", word)
    for value, length in runs([int(v) for v in p]):
        if length >= 127:
            out += bytes([value << 7 | 127]) + struct.pack("<H", length)
        else:
            out.append(value << 7 | length)
    return bytes(out)


def events():
    """About 5200 events on a 640 x 480 sensor with the codec's edge cases."""
    rng = np.random.default_rng(7)
    t, x, y, p = [], [], [], []
    now = 1_000_000

    def add(n, step, row=None, col=None, pol=None):
        nonlocal now
        for k in range(n):
            now += step(k)
            t.append(now)
            x.append(col(k) if col else int(rng.integers(0, 640)))
            y.append(row(k) if row else int(rng.integers(0, 480)))
            p.append(pol(k) if pol else int(rng.integers(0, 2)))

    add(1500, lambda k: int(rng.choice([0, 0, 1, 3, 14, 15, 16, 200])))
    add(40, lambda k: 0, row=lambda k: 17)                      # a run of 40 equal times and rows
    add(300, lambda k: int(k % 3 == 0), row=lambda k: 100 + k // 60,
        col=lambda k: 10 + k % 60, pol=lambda k: int(k < 200))  # neighbouring columns, long p runs
    add(1, lambda k: 1 << 40)                                   # a 2^40 µs step
    add(1, lambda k: 70_000)
    add(3400, lambda k: int(rng.integers(0, 4)))
    return (np.array(t, np.int64), np.array(x, np.uint16), np.array(y, np.uint16),
            np.array(p, np.uint8))


def indexes(t):
    """`/CD/indexes` as Metavision writes them: (0, -1), then per 2000 µs bin the first event
    at or after it, up to the long step (a row per bin across 2^40 µs would not fit)."""
    rel = t - t[0]
    rows = [(0, -1)]
    for k in range(int(rel[rel < 10**7].max() // 2000) + 1):
        rows.append((int(np.searchsorted(rel, 2000 * k)), 2000 * k))
    return np.array(rows, INDEX)


def smallest(x, y, p, t):
    """The ECF buffer of the smallest coordinate layout."""
    return min((ecf_encode(x, y, p, t, layout) for layout in range(3)), key=len)


def metavision(path, t, x, y, p, compressed, chunk=1000, encode=None, geometry="640x480"):
    with h5py.File(path, "w") as f:
        f.attrs["geometry"] = geometry
        f.attrs["serial_number"] = "fixture"
        f.attrs["format"] = "EVT3"
        f.attrs["time_shift"] = str(int(t[0]))
        cd = f.create_group("CD")
        if compressed:
            space = h5py.h5s.create_simple((len(t),), (h5py.h5s.UNLIMITED,))
            dcpl = h5py.h5p.create(h5py.h5p.DATASET_CREATE)
            dcpl.set_chunk((chunk,))
            dcpl.set_filter(ECF, h5py.h5z.FLAG_OPTIONAL)
            tid = h5py.h5t.py_create(CD, logical=True)
            dsid = h5py.h5d.create(cd.id, b"events", tid, space, dcpl=dcpl)
            for k, start in enumerate(range(0, len(t), chunk)):
                s = slice(start, start + chunk)
                buf = (encode(x[s], y[s], p[s], t[s]) if encode
                       else ecf_encode(x[s], y[s], p[s], t[s], k % 3))
                dsid.write_direct_chunk((start,), buf, filter_mask=0)
        else:
            rec = np.zeros(len(t), CD)
            rec["x"], rec["y"], rec["p"], rec["t"] = x, y, p, t
            cd.create_dataset("events", data=rec, chunks=(chunk,))
        idx = cd.create_dataset("indexes", data=indexes(t))
        idx.attrs["offset"] = str(-int(t[0]))
        trig = f.create_group("EXT_TRIGGER")
        tr = np.zeros(4, TRIGGER)
        tr["p"], tr["t"], tr["id"] = [1, 0, 1, 0], t[[100, 900, 2000, 4000]] + 1, [0, 0, 3, 3]
        trig.create_dataset("events", data=tr)


def dsec(path, t, x, y, p):
    offset = 900_000
    rel = t - offset
    with h5py.File(path, "w") as f:
        g = f.create_group("events")
        g.create_dataset("x", data=x)
        g.create_dataset("y", data=y)
        g.create_dataset("t", data=rel.astype(np.uint32) if rel.max() < 2**32 else rel)
        g.create_dataset("p", data=p)
        f.create_dataset("t_offset", data=np.int64(offset))
        ms = np.searchsorted(rel, 1000 * np.arange(int(rel[-1] // 1000) + 1))
        f.create_dataset("ms_to_idx", data=ms.astype(np.uint64))


def expected(path, t, x, y, p):
    np.savez_compressed(path, t=t, x=x, y=y, p=p)


def convert(source, output, geometry):
    """`source`: an .npz of columns t, x, y, p (as `ebiv convert` writes)."""
    ev = np.load(source)
    t, x, y, p = (ev[k] for k in ("t", "x", "y", "p"))
    metavision(output, t.astype(np.int64), x.astype(np.uint16), y.astype(np.uint16),
               (p > 0).astype(np.uint8), compressed=True, chunk=16384, encode=smallest,
               geometry=geometry)


def main():
    import argparse
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--from", dest="source", help="an .npz of event columns to convert")
    parser.add_argument("-o", "--output", help="the HDF5 file to write (with --from)")
    parser.add_argument("--geometry", default="1280x720", help="sensor size (with --from)")
    args = parser.parse_args()
    if args.source:
        convert(args.source, args.output, args.geometry)
        return
    t, x, y, p = events()
    metavision(HERE / "metavision_ecf.hdf5", t, x, y, p, compressed=True)
    metavision(HERE / "metavision_plain.hdf5", t, x, y, p, compressed=False)
    expected(HERE / "metavision.expected.npz", t, x, y, p)
    # DSEC's time fits 32 bits: the same events without the 2^40 µs step.
    keep = t < t[0] + (1 << 39)
    td = np.concatenate([t[keep], t[~keep] - (1 << 40)])
    dsec(HERE / "dsec_columns.h5", td, x, y, p)
    expected(HERE / "dsec.expected.npz", td, x, y, p)


if __name__ == "__main__":
    main()
