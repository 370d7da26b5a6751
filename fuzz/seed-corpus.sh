#!/usr/bin/env bash
# Build seed corpora for the fuzz targets from the shared sample recordings and small files
# written by ebiv itself, so the fuzzers start inside each format instead of at its magic bytes.
# Usage: fuzz/seed-corpus.sh [DATA_DIR]   (default: $EBIV_TEST_DATA or ../shared/data)
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
data=${1:-${EBIV_TEST_DATA:-$here/../../shared/data}}
ebiv=${EBIV_BIN:-$here/../target/release/ebiv}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

# seed TARGET FILE: flags byte 0, then the first 32 KiB of FILE.
seed() {
  mkdir -p "$here/corpus/$1"
  { printf '\x00'; head -c 32768 "$2"; } > "$here/corpus/$1/seed-$(basename "$2")"
  mkdir -p "$here/corpus/detect"
  cp "$here/corpus/$1/seed-$(basename "$2")" "$here/corpus/detect/"
}

seed raw_evt2 "$data/prophesee/evt2_sample.raw"
seed raw_header "$data/prophesee/evt2_sample.raw"
seed raw_evt3 "$data/prophesee/evt3_test_pedestrians.raw"
seed raw_header "$data/prophesee/evt3_test_pedestrians.raw"
seed dat "$data/prophesee/sample_ncars.dat"
seed aedat4 "$data/inivation/sample.aedat4"
seed es "$data/es/dvs.es"
seed npz "$data/ebiv/wallflow_slice2.npz"
seed hdf5 "$data/hdf5/ecf_small.hdf5"
seed hdf5 "$data/hdf5/generic_dsec.h5"
seed hdf5 "$here/../crates/ebiv/tests/data/hdf5/metavision_ecf.hdf5"

"$ebiv" convert "$data/prophesee/sample_ncars.dat" "$tmp/s.csv" --geometry 128x128
"$ebiv" convert "$data/prophesee/sample_ncars.dat" "$tmp/s.npy" --geometry 128x128
"$ebiv" convert "$data/prophesee/sample_ncars.dat" "$tmp/s.npz" --geometry 128x128
"$ebiv" convert "$data/prophesee/sample_ncars.dat" "$tmp/s21.raw" --geometry 128x128 --output-encoding evt21
"$ebiv" convert "$data/prophesee/sample_ncars.dat" "$tmp/s.aedat4" --geometry 128x128 2>/dev/null || true
seed text "$tmp/s.csv"
seed npy "$tmp/s.npy"
seed npz "$tmp/s.npz"
seed raw_evt21 "$tmp/s21.raw"
[ -f "$tmp/s.aedat4" ] && seed aedat4 "$tmp/s.aedat4"

# Formats ebiv does not write: a valid header and a few records.
printf '#!AER-DAT2.0\r\n# AEChip: ch.unizh.ini.jaer.chip.retina.DVS128\r\n\x00\x00\x01\x02\x00\x00\x00\x10\x00\x00\x40\x81\x00\x00\x00\x20' > "$tmp/s.aedat"
seed aedat2 "$tmp/s.aedat"
python3 - "$tmp" <<'PY'
import struct, sys
d = sys.argv[1]
hdr = b"#!AER-DAT3.1\r\n#Format: RAW\r\n#Source 1: DVS128\r\n#!END-HEADER\r\n"
events = b"".join(struct.pack("<Ii", (x << 17) | (y << 2) | (p << 1) | 1, 100 + i) for i, (x, y, p) in enumerate([(1, 2, 1), (3, 4, 0), (5, 6, 1)]))
packet = struct.pack("<hhiiiiii", 1, 1, 8, 4, 0, 3, 3, 3) + events
open(f"{d}/s31.aedat", "wb").write(hdr + packet)
recs = [(10, 20, 1, 0), (11, 21, 0, 5), (12, 22, 1, 9)]
body = b"".join(struct.pack("<HHI", x, y, (t << 1) | p) for x, y, p, t in recs)
head = b"EVT3" + b"\0" * 4 + struct.pack("<QQQIIII", 64 + len(body), len(recs), 1000, 9, 64, 640, 480) + b"\0" * 16
open(f"{d}/s.evt", "wb").write(head + body)
PY
seed aedat31 "$tmp/s31.aedat"
seed ebiv_evt "$tmp/s.evt"
echo "seed corpora in $here/corpus"
