#pragma once
// A file read first in a child process, where a library that crashes on it takes only the child down.
//
// HDF5 (and libmatio, which reads MATLAB v7.3 through it) dereferences addresses a damaged file gives it
// without checking them: a channel file damaged in transfer or by a crashed writer can end `process` with a
// segmentation fault instead of an error. signals/hdf5_layout.hpp checks the structures HDF5 is known to
// trust before it reads; this is the net under that check for whatever it does not cover. The read runs
// once in a fork of this process, whose only job is to survive it: a child killed by a signal, or ended by
// anything but a normal exit, means the file is refused with an error naming it. The parent then reads the
// file itself (the child's result is not carried back), so the file costs two reads.
#include <functional>
#include <string>

namespace tirstrain::signals {

// Runs `read` in a child process. Throws Error (file: `path`) when the child does not end normally;
// `library` names what read it in the message. An exception `read` throws ends the child normally: the
// parent's own read reports it. When no child can be started, returns without reading.
void survive_read_in_child(const std::string& path, const std::string& library,
                           const std::function<void()>& read);

}  // namespace tirstrain::signals
