#pragma once
// Checks of an HDF5 file's own structure, made before HDF5 (or libmatio, for MATLAB v7.3) opens it: HDF5
// 1.10 trusts some addresses in a damaged file and allocates gigabytes or reads through a null pointer
// instead of reporting the damage. Each check refuses only what the format rules out for a file written by
// HDF5's default driver; whatever it does not recognise it leaves to HDF5.
#include <string>

namespace tirstrain::signals {

// Throws tirstrain::Error naming `path` when the file's superblock names a driver information block (a
// multi-file driver or a damaged superblock), or when the index of a group reachable from the root (its
// symbol-table message, B-tree nodes and symbol-table nodes) points outside the file or at something that
// is not the node the format says.
void check_hdf5_layout(const std::string& path);

}  // namespace tirstrain::signals
