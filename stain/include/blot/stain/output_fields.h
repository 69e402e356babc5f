#pragma once
/// How an output record lists its fields once. MassBudget, StepProfile,
/// coupling::CoupledStepTimes, engine::PhaseTotals and engine::EngineStatistics
/// each have a `fields(self, visitor)` member, as StainState does for the
/// state; every output is a visitor over that list:
///  - Python dicts (python/src/module.cpp, `pythonDict`),
///  - JSON (engine/outputs/include/blot/engine/output_json.h: the mass budget
///    of `blot run`/`blot demo`, summary.json's statistics and mean times),
///  - the C API structs (engine/src/c_api.cpp: the copy into blotMassBudget and
///    blotStatistics is generated from the list, and a static_assert there
///    fails the build when a listed field has no C member or a C member no
///    listed field),
///  - the viewer's panels (demos/viewer/viewer.cpp).
/// A `static_assert(describesEveryMember<Record>())` beside each list fails the
/// build when a member is added to the struct but not to its list.
/// docs/architecture.md, "Where a new output field goes", walks through it.
///
/// What a list calls on its visitor (each call names the field with an
/// OutputField):
///   v.field(info, member)            a number: double, int, unsigned, std::int64_t
///   v.computed(info, getter)         a value derived from the others (getter()
///                                    returns double or std::string), not a member
///   v.record(info, member)           a nested record with its own fields()
///   v.perStage(info, array, first, last)  std::array<double, kStageCount>: one
///                                    value per Stage from first to last (keys
///                                    from stageKey, so a new Stage is listed)
///   v.perTerm(info, array)           std::array<std::int64_t, kStepTermCount>:
///                                    one value per StepTerm (keys from stepTermName)
#include <cstddef>
#include <utility>

namespace blot::stain {

/// The outputs a listed field goes to (OutputField::targets). A field goes to
/// every output unless its line says otherwise; the exceptions keep outputs
/// as they were when the lists were written (e.g. the Python profile dict
/// holds a few of the profile's counters).
enum OutputTarget : unsigned {
  kPythonOutput = 1u << 0,  ///< the Python dicts
  kJsonOutput = 1u << 1,    ///< JSON
  kCOutput = 1u << 2,       ///< the C API structs
  kEveryOutput = kPythonOutput | kJsonOutput | kCOutput,
};

/// What a value is to a panel that shows it (the viewer's mass budget): a part
/// of its group's total, the total, or the group's relative error.
enum class FieldRole { Value, Part, Total, Error };

/// One listed field: its names in each output and where it goes. Built with
/// outputField(name, key, unit) and the chained setters below, all constexpr.
struct OutputField {
  const char* name = "";        ///< the C++ member's name, camelCase (C struct members are checked against it)
  const char* key = "";         ///< snake_case key in Python dicts and JSON
  const char* unit = "";        ///< SI unit ("kg", "ms", "s"; "" for counts and ratios)
  const char* label = "";       ///< short label in the viewer's panels ("": the key, '_' read as ' ')
  const char* group = nullptr;  ///< JSON: the object it sits in ("solvent"), nullptr: at the top
  const char* groupKey = nullptr;  ///< its key inside `group` ("free", "relative_error")
  const char* jsonKey = nullptr;   ///< JSON key when it differs from `key`; for perStage, the keys' prefix
  FieldRole role = FieldRole::Value;
  unsigned targets = kEveryOutput;  ///< OutputTarget bits
  bool perStep = false;  ///< JSON writes its numbers divided by the step count (means of sums)

  constexpr OutputField labelled(const char* text) const {
    OutputField f = *this;
    f.label = text;
    return f;
  }
  constexpr OutputField inGroup(const char* name_, const char* keyInGroup) const {
    OutputField f = *this;
    f.group = name_;
    f.groupKey = keyInGroup;
    return f;
  }
  constexpr OutputField json(const char* jsonKey_) const {
    OutputField f = *this;
    f.jsonKey = jsonKey_;
    return f;
  }
  constexpr OutputField as(FieldRole role_) const {
    OutputField f = *this;
    f.role = role_;
    return f;
  }
  /// A part of `group_`'s total, under keyInGroup in JSON.
  constexpr OutputField partOf(const char* group_, const char* keyInGroup) const {
    return inGroup(group_, keyInGroup).as(FieldRole::Part);
  }
  /// The total of `group_` (the parts' sum), under keyInGroup in JSON.
  constexpr OutputField totalOf(const char* group_, const char* keyInGroup) const {
    return inGroup(group_, keyInGroup).as(FieldRole::Total);
  }
  /// The relative error of `group_`'s balance, under keyInGroup in JSON.
  constexpr OutputField errorOf(const char* group_, const char* keyInGroup = "relative_error") const {
    return inGroup(group_, keyInGroup).as(FieldRole::Error);
  }
  /// Kept out of the outputs in `targets` (OutputTarget bits).
  constexpr OutputField notIn(unsigned targets_) const {
    OutputField f = *this;
    f.targets &= ~targets_;
    return f;
  }
  constexpr OutputField meanPerStep() const {
    OutputField f = *this;
    f.perStep = true;
    return f;
  }
  constexpr bool goesTo(unsigned target) const { return (targets & target) != 0; }
  /// The JSON key (jsonKey, else key).
  constexpr const char* jsonName() const { return jsonKey != nullptr ? jsonKey : key; }
};

/// A field named `name` in C++ and C, `key` in Python and JSON, in `unit`.
constexpr OutputField outputField(const char* name, const char* key, const char* unit = "") {
  OutputField f;
  f.name = name;
  f.key = key;
  f.unit = unit;
  return f;
}

namespace output_detail {

constexpr bool sameText(const char* a, const char* b) {
  while (*a != '\0' && *a == *b) ++a, ++b;
  return *a == *b;
}

/// Counts the members a list names (field, record, perStage, perTerm; not
/// computed values) and checks that no two lines share a name or a key.
struct MemberCounter {
  static constexpr int kCapacity = 64;
  int count = 0;
  int lines = 0;
  bool unique = true;
  OutputField fields[kCapacity] = {};

  constexpr void line(const OutputField& f, bool member) {
    if (member) ++count;
    if (lines >= kCapacity) {
      unique = false;
      return;
    }
    for (int k = 0; k < lines; ++k)
      if (sameText(fields[k].name, f.name) || sameText(fields[k].key, f.key)) unique = false;
    fields[lines++] = f;
  }
  template <class T> constexpr void field(const OutputField& f, T&) { line(f, true); }
  template <class F> constexpr void computed(const OutputField& f, F&&) { line(f, false); }
  template <class R> constexpr void record(const OutputField& f, R&) { line(f, true); }
  template <class A, class S> constexpr void perStage(const OutputField& f, A&, S, S) { line(f, true); }
  template <class A> constexpr void perTerm(const OutputField& f, A&) { line(f, true); }
};

/// Converts to any member type, to count an aggregate's members.
struct AnyMember {
  template <class T> constexpr operator T() const;  // never called (unevaluated)
};

template <class T, class Indices, class = void>
struct BracesWith : std::false_type {};
template <class T, std::size_t... I>
struct BracesWith<T, std::index_sequence<I...>, std::void_t<decltype(T{(void(I), AnyMember{})...})>>
    : std::true_type {};

/// The number of members of aggregate T: the most initializers T{…} takes.
template <class T, std::size_t N = 0>
constexpr std::size_t aggregateMemberCount() {
  if constexpr (N > 64) {
    return N;  // more than any record has; the static_assert reports it
  } else if constexpr (BracesWith<T, std::make_index_sequence<N + 1>>::value) {
    return aggregateMemberCount<T, N + 1>();
  } else {
    return N;
  }
}

}  // namespace output_detail

/// True when Record's fields() names as many members as Record has, and no
/// two of its lines share a name or a key: a member added to the struct
/// without a line in its list (or a line copied without renaming) fails the
/// static_assert beside the list.
template <class Record>
constexpr bool describesEveryMember() {
  Record record{};
  output_detail::MemberCounter counter;
  Record::fields(record, counter);
  return counter.unique && static_cast<std::size_t>(counter.count) == output_detail::aggregateMemberCount<Record>();
}

}  // namespace blot::stain
