#pragma once
/// JSON of a listed output record (stain/output_fields.h): every field whose
/// line goes to JSON, under its JSON key (OutputField::jsonName), inside its
/// group's object when it has one; a nested record as an object; a per-stage
/// array as one key per stage, the field's JSON key + stain::stageKey
/// ("stain_advect_velocity"); a per-term array as one key per term that
/// counted (stain::stepTermName). Numbers keep their C++ type (an int is a
/// JSON integer). Fields marked meanPerStep (and everything in a record so
/// marked) are divided by `steps`.
#include <blot/stain/output_fields.h>
#include <blot/stain/step_profile.h>

#include <nlohmann/json.hpp>

#include <array>
#include <cstdint>
#include <string>

namespace blot::engine {

template <class Record>
nlohmann::json outputJson(const Record& record, double steps = 1);

/// Per-term counts as {stepTermName: count} for the terms counted at least
/// once, e.g. {"gravity": 240, "density-diffusion-krylov": 238}.
inline nlohmann::json termCountsJson(const std::array<std::int64_t, stain::kStepTermCount>& counts) {
  nlohmann::json out = nlohmann::json::object();
  for (int k = 0; k < stain::kStepTermCount; ++k)
    if (counts[static_cast<size_t>(k)] > 0)
      out[stain::stepTermName(static_cast<stain::StepTerm>(1u << k))] = counts[static_cast<size_t>(k)];
  return out;
}

namespace output_json_detail {

class JsonWriter {
 public:
  JsonWriter(nlohmann::json& out, double steps, bool mean) : out_(out), steps_(steps), mean_(mean) {}

  template <class T>
  void field(const stain::OutputField& f, const T& value) {
    if (!f.goesTo(stain::kJsonOutput)) return;
    if (mean_ || f.perStep)
      slot(f) = static_cast<double>(value) / steps_;
    else
      slot(f) = value;
  }
  template <class Get>
  void computed(const stain::OutputField& f, Get&& get) {
    if (f.goesTo(stain::kJsonOutput)) slot(f) = get();
  }
  template <class Record>
  void record(const stain::OutputField& f, const Record& nested) {
    if (!f.goesTo(stain::kJsonOutput)) return;
    nlohmann::json& inner = slot(f);
    inner = nlohmann::json::object();
    JsonWriter writer(inner, steps_, mean_ || f.perStep);
    nested.visit(writer);
  }
  void perStage(const stain::OutputField& f, const std::array<double, stain::kStageCount>& values, stain::Stage first,
                stain::Stage last) {
    if (!f.goesTo(stain::kJsonOutput)) return;
    for (int k = static_cast<int>(first); k <= static_cast<int>(last); ++k) {
      const double value = values[static_cast<size_t>(k)];
      out_[f.jsonName() + stain::stageKey(static_cast<stain::Stage>(k))] = mean_ || f.perStep ? value / steps_ : value;
    }
  }
  void perTerm(const stain::OutputField& f, const std::array<std::int64_t, stain::kStepTermCount>& counts) {
    if (f.goesTo(stain::kJsonOutput)) slot(f) = termCountsJson(counts);
  }

 private:
  nlohmann::json& slot(const stain::OutputField& f) {
    return f.group != nullptr ? out_[f.group][f.groupKey] : out_[f.jsonName()];
  }

  nlohmann::json& out_;
  double steps_;
  bool mean_;
};

}  // namespace output_json_detail

template <class Record>
nlohmann::json outputJson(const Record& record, double steps) {
  nlohmann::json out = nlohmann::json::object();
  output_json_detail::JsonWriter writer(out, steps, false);
  record.visit(writer);
  return out;
}

}  // namespace blot::engine
