"""Makes the small HDF5 files io.test_checkpoint reads to test its error messages
(foreign.h5, checkpoint_version_999.h5, checkpoint_empty.h5). Run once with h5py; the
files are committed so the test needs no Python."""
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
