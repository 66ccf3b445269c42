#!/usr/bin/env python3
"""Writes the bad HDF5 session files of the bad-input corpus (tests/testdata/bad/cases.txt,
placeholder {made}) into the folder given, instead of keeping binaries in the repository.

session_huge_rows.h5   chunked datasets declaring 10^12 rows, never written (the reader once
                       tried to allocate 8 TB for them)
session_rank32.h5      /slot0/t a 32-D dataset (once overflowed a two-element extent array)
session_external_dev_zero.h5  datasets whose data is an external file, /dev/zero (once read
                       until memory ran out)
"""
import os
import sys

import h5py
import numpy as np


def huge_rows(path):
    n = 10**12
    with h5py.File(path, "w") as f:
        g = f.create_group("slot0")
        g.create_dataset("t", shape=(n,), chunks=(4,), dtype="<f8")
        g.create_dataset("position", shape=(n, 3), chunks=(4, 3), dtype="<f8")
        g.create_dataset("orientation", shape=(n, 4), chunks=(4, 4), dtype="<f8")


def rank32(path):
    with h5py.File(path, "w") as f:
        g = f.create_group("slot0")
        g.create_dataset("t", data=np.zeros((1,) * 32), dtype="<f8")
        g.create_dataset("position", data=np.zeros((1, 3)), dtype="<f8")
        g.create_dataset("orientation", data=np.array([[1.0, 0, 0, 0]]), dtype="<f8")


def external_dev_zero(path):
    n = 10**6
    with h5py.File(path, "w") as f:
        g = f.create_group("slot0")
        for name, cols in (("t", 0), ("position", 3), ("orientation", 4)):
            shape = (n,) if cols == 0 else (n, cols)
            size = 8 * n * max(cols, 1)
            g.create_dataset(name, shape=shape, dtype="<f8", external=[("/dev/zero", 0, size)])


if __name__ == "__main__":
    out = sys.argv[1]
    huge_rows(os.path.join(out, "session_huge_rows.h5"))
    rank32(os.path.join(out, "session_rank32.h5"))
    external_dev_zero(os.path.join(out, "session_external_dev_zero.h5"))
