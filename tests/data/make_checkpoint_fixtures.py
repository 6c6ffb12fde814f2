"""Makes the small HDF5 files io.test_checkpoint reads to test its error messages
(foreign.h5, checkpoint_version_999.h5, checkpoint_empty.h5) and the version-2 checkpoint
it reads back (checkpoint_version_2.h5). Run once with h5py; the files are committed so the
test needs no Python.

    python make_checkpoint_fixtures.py [RUN_H5]

RUN_H5: the version-3 checkpoint io.test_checkpoint writes (build/tests/run/
io_test_checkpoint/restart/run.h5); checkpoint_version_2.h5 is that file in the version-2
layout, the effective deck as one fixed-length string per line (deck/effective) in place
of deck/text and deck/line_ends, the layouts being otherwise the same."""
import shutil
import sys

import h5py
import numpy as np

# A valid HDF5 file that is not a checkpoint: no 'format' attribute.
with h5py.File("foreign.h5", "w") as f:
    f["values"] = np.arange(10.0)
    f.attrs["title"] = np.bytes_("some other program")
# A checkpoint of a future format version.
with h5py.File("checkpoint_version_999.h5", "w") as f:
    f.attrs["format"] = np.bytes_("ricochet-checkpoint")
    f.attrs["version"] = np.int32(999)
# Right format and version, but nothing else: damaged.
with h5py.File("checkpoint_empty.h5", "w") as f:
    f.attrs["format"] = np.bytes_("ricochet-checkpoint")
    f.attrs["version"] = np.int32(2)

if len(sys.argv) > 1:
    shutil.copyfile(sys.argv[1], "checkpoint_version_2.h5")
    with h5py.File("checkpoint_version_2.h5", "r+") as f:
        assert f.attrs["version"] == 3
        text = f["deck/text"][()].tobytes()
        ends = f["deck/line_ends"][()]
        starts = np.concatenate([[0], ends[:-1]])
        lines = [text[a:b] for a, b in zip(starts, ends)]
        width = max(1, max(len(x) for x in lines))
        del f["deck/text"], f["deck/line_ends"]
        f["deck"].create_dataset("effective", data=np.array(lines, dtype="S%d" % width))
        f.attrs["version"] = np.int32(2)
