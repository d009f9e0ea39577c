#include "signals/hdf5_layout.hpp"

#include <array>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <set>
#include <vector>

#include "core/error.hpp"

namespace tirstrain::signals {
namespace {

// HDF5's "undefined address": all ones.
constexpr std::uint64_t kUndefined = ~std::uint64_t{0};
// Bounds on the walk, so that a damaged file cannot make it long; beyond them HDF5 judges the rest.
constexpr int kMaxDepth = 32;
constexpr std::size_t kMaxNodes = 100000;

// Little-endian unsigned integer of n bytes.
std::uint64_t le(const unsigned char* p, int n) {
  std::uint64_t v = 0;
  for (int i = n - 1; i >= 0; --i) v = (v << 8) | p[i];
  return v;
}

// The file's bytes, read where asked.
class FileBytes {
 public:
  explicit FileBytes(const std::string& path) : in_(path, std::ios::binary) {
    std::error_code error;
    size_ = std::filesystem::file_size(path, error);
    if (error) size_ = 0;
  }
  std::uint64_t size() const { return size_; }
  // n bytes at absolute offset `at` into `out`; false when they are not all in the file.
  bool read(std::uint64_t at, std::size_t n, std::vector<unsigned char>& out) {
    if (at == kUndefined || at > size_ || n > size_ - at) return false;
    out.resize(n);
    in_.clear();
    in_.seekg(static_cast<std::streamoff>(at));
    in_.read(reinterpret_cast<char*>(out.data()), static_cast<std::streamsize>(n));
    return static_cast<std::size_t>(in_.gcount()) == n;
  }
  // Whether the 4-byte signature `sig` is at absolute offset `at`.
  bool has_signature(std::uint64_t at, const char* sig) {
    std::vector<unsigned char> b;
    return read(at, 4, b) && std::memcmp(b.data(), sig, 4) == 0;
  }

 private:
  std::ifstream in_;
  std::uint64_t size_ = 0;
};

// A group's symbol-table message: where its B-tree and its local heap (the members' names) are.
struct SymbolTable {
  std::uint64_t btree = kUndefined, heap = kUndefined;
};

// A version 0 or 1 superblock with 8-byte addresses and lengths, the layout HDF5's default driver writes
// unless asked for the newest format.
struct Superblock {
  std::uint64_t base = 0;  // absolute offset every address is relative to (where the superblock is)
  int leaf_k = 0;          // a symbol-table node holds up to 2 leaf_k entries
  int internal_k = 0;      // a group B-tree node up to 2 internal_k children
  std::uint64_t driver_info = kUndefined;
  std::uint64_t root_header = kUndefined;  // the root group's object header
  bool root_cached = false;                // whether its entry caches its symbol table (cache type 1)
  SymbolTable root_table;                  // that cached B-tree and heap

  // The absolute offset of `address` in a file of `size` bytes; kUndefined when it is not in the file.
  std::uint64_t absolute(std::uint64_t address, std::uint64_t size) const {
    return address < size - base ? base + address : kUndefined;
  }
};

// The superblock at 0, 512, 1024, … (a user block, such as MATLAB's text header, comes first); false when
// there is none of the kind Superblock describes.
bool find_superblock(FileBytes& file, Superblock& sb) {
  constexpr unsigned char kSignature[8] = {0x89, 'H', 'D', 'F', '\r', '\n', 0x1a, '\n'};
  std::vector<unsigned char> b;
  for (std::uint64_t at = 0; at < file.size(); at = at == 0 ? 512 : 2 * at) {
    if (!file.read(at, 8, b) || std::memcmp(b.data(), kSignature, 8) != 0) continue;
    if (!file.read(at, 16, b)) return false;
    const int version = b[8];
    if (version > 1 || b[13] != 8 || b[14] != 8) return false;
    if (!file.read(at, version == 0 ? 96 : 100, b)) return false;
    sb.base = at;
    sb.leaf_k = static_cast<int>(le(&b[16], 2));
    sb.internal_k = static_cast<int>(le(&b[18], 2));
    // Base, free-space, end-of-file and driver-information addresses, then the root group's entry: link
    // name offset, object header address, cache type, reserved, and a scratch pad with the B-tree address.
    const std::size_t p = version == 0 ? 24 : 28;
    sb.driver_info = le(&b[p + 24], 8);
    sb.root_header = le(&b[p + 40], 8);
    sb.root_cached = le(&b[p + 48], 4) == 1;
    sb.root_table = {le(&b[p + 56], 8), le(&b[p + 64], 8)};
    return true;
  }
  return false;
}

// The symbol-table message of the version 1 object header at `header`; false when there is none in its
// first block (not a group, a group of the newer kind, or messages continued elsewhere).
bool symbol_table_message(FileBytes& file, const Superblock& sb, std::uint64_t header, SymbolTable& out) {
  std::vector<unsigned char> b;
  const std::uint64_t at_header = sb.absolute(header, file.size());
  if (!file.read(at_header, 16, b) || b[0] != 1) return false;
  const std::uint64_t messages = le(&b[2], 2), size = le(&b[8], 4);
  const std::size_t readable =
      static_cast<std::size_t>(std::min<std::uint64_t>(size, file.size() - at_header - 16));
  if (!file.read(at_header + 16, std::min<std::size_t>(readable, 1 << 16), b)) return false;
  std::size_t at = 0;
  for (std::uint64_t m = 0; m < messages && at + 8 <= b.size(); ++m) {
    const std::uint64_t type = le(&b[at], 2), length = le(&b[at + 2], 2);
    if (at + 8 + length > b.size()) break;
    if (type == 0x11 && length >= 16) {
      out = {le(&b[at + 8], 8), le(&b[at + 16], 8)};
      return true;
    }
    at += 8 + static_cast<std::size_t>(length);
  }
  return false;
}

// Walks the groups from the root, checking that every address their indexes hold lies in the file and
// leads to the kind of node the format says: a group's symbol-table message (and the copy its entry may
// cache) to a group B-tree node and a local heap, a B-tree node's siblings and inner children to B-tree
// nodes, a leaf's children to symbol-table nodes, whose entries lead on to the members.
class GroupIndexWalk {
 public:
  GroupIndexWalk(FileBytes& file, const Superblock& sb, const std::string& path)
      : file_(file), sb_(sb), path_(path) {}

  // The group or other object whose header is at `header`; `cached` the B-tree and heap its entry caches
  // (cache type 1), if any.
  void object(std::uint64_t header, const SymbolTable* cached, int depth) {
    if (depth > kMaxDepth || visited_.size() >= kMaxNodes || !visited_.insert(header).second) return;
    SymbolTable table;
    if (symbol_table_message(file_, sb_, header, table)) group(header, table, depth);
    if (cached != nullptr) group(header, *cached, depth);
  }

 private:
  void group(std::uint64_t header, const SymbolTable& table, int depth) {
    expect(header, table.heap, "HEAP");
    expect(header, table.btree, "TREE");
    tree(table.btree, depth);
  }

  void tree(std::uint64_t address, int depth) {
    if (depth > kMaxDepth || visited_.size() >= kMaxNodes || !visited_.insert(address).second) return;
    std::vector<unsigned char> b;
    const std::uint64_t at = sb_.absolute(address, file_.size());
    if (!file_.read(at, 24, b)) damaged(address, "runs past the end of the file");
    const int level = b[5];
    const std::uint64_t entries = le(&b[6], 2);
    if (b[4] != 0) damaged(address, "is a group's B-tree node of type " + std::to_string(b[4]) + ", not 0");
    if (sb_.internal_k > 0 && entries > 2 * static_cast<std::uint64_t>(sb_.internal_k))
      damaged(address,
              "holds " + std::to_string(entries) + " entries, more than the file's node size allows");
    for (const std::uint64_t sibling : {le(&b[8], 8), le(&b[16], 8)})
      if (sibling != kUndefined) expect(address, sibling, "TREE");
    // Keys (heap offsets) and child addresses alternate after the 24-byte header: key, child, …, key.
    if (!file_.read(at + 24, static_cast<std::size_t>(16 * entries + 8), b))
      damaged(address, "runs past the end of the file");
    for (std::uint64_t k = 0; k < entries; ++k) {
      const std::uint64_t child = le(&b[16 * k + 8], 8);
      if (level > 0) {
        expect(address, child, "TREE");
        tree(child, depth + 1);
      } else {
        expect(address, child, "SNOD");
        symbols(child, depth);
      }
    }
  }

  // A symbol-table node: its entries must lie in the file; an entry caching a group's B-tree leads on.
  void symbols(std::uint64_t address, int depth) {
    if (visited_.size() >= kMaxNodes || !visited_.insert(address).second) return;
    std::vector<unsigned char> b;
    const std::uint64_t at = sb_.absolute(address, file_.size());
    if (!file_.read(at, 8, b)) return;
    const std::uint64_t count = le(&b[6], 2);
    if (sb_.leaf_k > 0 && count > 2 * static_cast<std::uint64_t>(sb_.leaf_k))
      damaged(address, "holds " + std::to_string(count) + " symbols, more than the file's node size allows");
    if (!file_.read(at + 8, static_cast<std::size_t>(40 * count), b))
      damaged(address, "runs past the end of the file");
    for (std::uint64_t e = 0; e < count; ++e) {
      const unsigned char* entry = &b[40 * e];
      const std::uint64_t header = le(entry + 8, 8), cache_type = le(entry + 16, 4);
      // A soft link's entry (cache type 2) names no object header.
      if (cache_type != 2 && sb_.absolute(header, file_.size()) == kUndefined)
        damaged(address, "names an object header at " + where(header) + ", outside the file");
      if (cache_type == 2) continue;
      const SymbolTable cached{le(entry + 24, 8), le(entry + 32, 8)};
      object(header, cache_type == 1 ? &cached : nullptr, depth + 1);
    }
  }

  void expect(std::uint64_t from, std::uint64_t to, const char* signature) {
    if (sb_.absolute(to, file_.size()) == kUndefined)
      damaged(from, "points to " + where(to) + ", outside the file");
    if (!file_.has_signature(sb_.base + to, signature))
      damaged(from,
              "points to byte " + std::to_string(sb_.base + to) + ", which is not a " + kind_of(signature));
  }

  static std::string kind_of(const char* signature) {
    if (std::strcmp(signature, "TREE") == 0) return "B-tree node";
    if (std::strcmp(signature, "SNOD") == 0) return "symbol-table node";
    return "local heap";
  }

  std::string where(std::uint64_t address) const {
    return address == kUndefined ? "an undefined address" : "address " + std::to_string(address);
  }

  [[noreturn]] void damaged(std::uint64_t node, const std::string& what) const {
    throw Error("a group's index is damaged: the node at byte " + std::to_string(sb_.base + node) + " " +
                    what + " (refused before HDF5 reads it: HDF5 1.10 can crash on such a file)",
                {.file = path_});
  }

  FileBytes& file_;
  const Superblock& sb_;
  const std::string& path_;
  std::set<std::uint64_t> visited_;
};

}  // namespace

void check_hdf5_layout(const std::string& path) {
  FileBytes file(path);
  Superblock sb;
  if (!find_superblock(file, sb)) return;  // not HDF5, or a layout HDF5 judges on its own
  // HDF5 1.10 reads a version 0/1 superblock's driver information block before checking it, allocating the
  // size it claims (gigabytes, in a damaged file); channel files (MATLAB v7.3, h5py, HDF5's default driver)
  // never have one.
  if (sb.driver_info != kUndefined)
    throw Error(
        "names a driver information block (a multi-file HDF5 driver, or a damaged superblock); "
        "channel files use HDF5's default driver",
        {.file = path});
  // The root group, as its object header describes it and as the superblock's entry may cache it.
  GroupIndexWalk walk(file, sb, path);
  walk.object(sb.root_header, sb.root_cached ? &sb.root_table : nullptr, 0);
}

}  // namespace tirstrain::signals
