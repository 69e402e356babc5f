#pragma once
// The C API's output structs (blot.h) filled from the C++ records' field lists
// (stain/output_fields.h). A C struct stays a plain C declaration; beside it,
// c_api.cpp lists its members once, each with the listed field it holds
// (`cMembers(blotStatistics&, visitor)`: v.member("lastTimes.total",
// c.lastStepMilliseconds), v.nested("massBudget", c.massBudget)). From the two
// lists:
//  - cStructMirrors<Record, CStruct>() checks at compile time that every field
//    listed for C has a member of the same type, every member a listed field,
//    and that the members fill the struct (a C member missing from cMembers);
//  - copyToC(record, cStruct) does the copy, matching by name.
// A field reaches a member by its path of names ("massBudget.freeSolvent",
// "lastTimes.total"), so the C struct may order and flatten as its ABI needs.
#include <blot/stain/output_fields.h>

#include <cstddef>
#include <cstdint>
#include <string>
#include <type_traits>
#include <utility>

namespace blot::engine::c_struct_copy {

enum class Kind { Double, Int, Int64, Unsigned, Unsupported };

template <class T>
constexpr Kind kindOf() {
  using U = std::remove_cv_t<std::remove_reference_t<T>>;
  if constexpr (std::is_same_v<U, double>) return Kind::Double;
  else if constexpr (std::is_same_v<U, int>) return Kind::Int;
  else if constexpr (std::is_same_v<U, std::int64_t>) return Kind::Int64;
  else if constexpr (std::is_same_v<U, unsigned>) return Kind::Unsigned;
  else return Kind::Unsupported;  // text, arrays, records: no C member holds them
}

/// A field's path: the names of the records around it, then its own; a name
/// may itself hold dots ("lastTimes.total"), the path reads as one dotted text.
struct Path {
  static constexpr int kMaxDepth = 4;
  const char* names[kMaxDepth] = {};
  int depth = 0;
  constexpr Path then(const char* name) const {
    Path p = *this;
    if (p.depth < kMaxDepth) p.names[p.depth] = name;
    ++p.depth;
    return p;
  }
};

/// Walks a Path's dotted text one character at a time.
class PathReader {
 public:
  constexpr explicit PathReader(const Path& path) : path_(path), at_(path.depth > 0 ? path.names[0] : "") {}
  /// The next character, '\0' at the end.
  constexpr char next() {
    if (*at_ != '\0') return *at_++;
    if (segment_ + 1 >= path_.depth) return '\0';
    at_ = path_.names[++segment_];
    return '.';
  }

 private:
  const Path& path_;
  int segment_ = 0;
  const char* at_;
};

constexpr bool samePath(const Path& a, const Path& b) {
  if (a.depth > Path::kMaxDepth || b.depth > Path::kMaxDepth) return false;
  PathReader ra(a), rb(b);
  for (;;) {
    const char ca = ra.next(), cb = rb.next();
    if (ca != cb) return false;
    if (ca == '\0') return true;
  }
}

/// One field or member: where, what type, its size in the C struct.
struct Leaf {
  Path path;
  Kind kind = Kind::Unsupported;
  std::size_t size = 0;
  double real = 0;          // copyToC: the value of a Double
  std::int64_t integer = 0;  // copyToC: the value of the integer kinds
};

struct Leaves {
  static constexpr int kCapacity = 64;
  Leaf items[kCapacity] = {};
  int count = 0;
  constexpr Leaf* add(const Path& path, Kind kind, std::size_t size) {
    if (count >= kCapacity) {
      ++count;  // reported as a mismatch
      return nullptr;
    }
    Leaf& leaf = items[count++];
    leaf.path = path;
    leaf.kind = kind;
    leaf.size = size;
    return &leaf;
  }
  constexpr const Leaf* find(const Path& path) const {
    for (int k = 0; k < count && k < kCapacity; ++k)
      if (samePath(items[k].path, path)) return &items[k];
    return nullptr;
  }
};

/// Visits a record's list, keeping the fields that go to C (with their values
/// when `withValues`).
template <bool withValues>
class ListedLeaves {
 public:
  constexpr ListedLeaves(Leaves& out, const Path& prefix) : out_(out), prefix_(prefix) {}

  template <class T>
  constexpr void field(const stain::OutputField& f, T& value) {
    if (!f.goesTo(stain::kCOutput)) return;
    Leaf* leaf = out_.add(prefix_.then(f.name), kindOf<T>(), sizeof(T));
    if constexpr (withValues) store(leaf, value);
  }
  template <class Get>
  constexpr void computed(const stain::OutputField& f, Get&& get) {
    if (!f.goesTo(stain::kCOutput)) return;
    using T = decltype(get());
    Leaf* leaf = out_.add(prefix_.then(f.name), kindOf<T>(), sizeof(T));
    if constexpr (withValues) store(leaf, get());
  }
  template <class Record>
  constexpr void record(const stain::OutputField& f, Record& nested) {
    if (!f.goesTo(stain::kCOutput)) return;
    ListedLeaves inner(out_, prefix_.then(f.name));
    std::remove_const_t<Record>::fields(nested, inner);
  }
  template <class Array, class Stage>
  constexpr void perStage(const stain::OutputField& f, Array&, Stage, Stage) {
    if (f.goesTo(stain::kCOutput)) out_.add(prefix_.then(f.name), Kind::Unsupported, 0);
  }
  template <class Array>
  constexpr void perTerm(const stain::OutputField& f, Array&) {
    if (f.goesTo(stain::kCOutput)) out_.add(prefix_.then(f.name), Kind::Unsupported, 0);
  }

 private:
  template <class T>
  static constexpr void store(Leaf* leaf, const T& value) {
    if (leaf == nullptr) return;
    if constexpr (kindOf<T>() == Kind::Double)
      leaf->real = value;
    else if constexpr (kindOf<T>() != Kind::Unsupported)
      leaf->integer = static_cast<std::int64_t>(value);
  }

  Leaves& out_;
  Path prefix_;
};

/// Visits a C struct's member list (cMembers), collecting its members.
class CMemberLeaves {
 public:
  constexpr CMemberLeaves(Leaves& out, const Path& prefix) : out_(out), prefix_(prefix) {}
  template <class T>
  constexpr void member(const char* field, T&) {
    out_.add(prefix_.then(field), kindOf<T>(), sizeof(T));
  }
  template <class CStruct>
  constexpr void nested(const char* field, CStruct& c) {
    CMemberLeaves inner(out_, prefix_.then(field));
    cMembers(c, inner);
  }

 private:
  Leaves& out_;
  Path prefix_;
};

/// Writes the listed values into the C members they name.
class CMemberWriter {
 public:
  CMemberWriter(const Leaves& values, const Path& prefix) : values_(values), prefix_(prefix) {}
  template <class T>
  void member(const char* field, T& out) {
    const Leaf* leaf = values_.find(prefix_.then(field));
    if (leaf == nullptr) return;  // cStructMirrors rules this out at compile time
    if constexpr (kindOf<T>() == Kind::Double)
      out = leaf->real;
    else
      out = static_cast<T>(leaf->integer);
  }
  template <class CStruct>
  void nested(const char* field, CStruct& c) {
    CMemberWriter inner(values_, prefix_.then(field));
    cMembers(c, inner);
  }

 private:
  const Leaves& values_;
  Path prefix_;
};

/// True when CStruct's member list (cMembers) and Record's field list agree:
/// the same paths, the same types, and members that fill CStruct.
template <class Record, class CStruct>
constexpr bool cStructMirrors() {
  Record record{};
  CStruct c{};
  Leaves listed, members;
  ListedLeaves<false> listedVisitor(listed, Path{});
  Record::fields(record, listedVisitor);
  CMemberLeaves memberVisitor(members, Path{});
  cMembers(c, memberVisitor);
  if (listed.count != members.count || members.count > Leaves::kCapacity) return false;
  std::size_t bytes = 0;
  for (int k = 0; k < members.count; ++k) {
    const Leaf& m = members.items[k];
    const Leaf* l = listed.find(m.path);
    if (l == nullptr || l->kind != m.kind || m.kind == Kind::Unsupported) return false;
    if (members.find(listed.items[k].path) == nullptr) return false;
    bytes += m.size;
  }
  return bytes == sizeof(CStruct);
}

/// Fills `c` from `record` (every member; cStructMirrors holds).
template <class Record, class CStruct>
void copyToC(const Record& record, CStruct& c) {
  Leaves values;
  ListedLeaves<true> listedVisitor(values, Path{});
  Record::fields(record, listedVisitor);
  CMemberWriter writer(values, Path{});
  cMembers(c, writer);
}

}  // namespace blot::engine::c_struct_copy
