// blot_viewer_stain_pixels: counts the pixels of a pigment's hue in a
// screenshot of blot-viewer, to check that a stain is visible in it.
//
//   blot_viewer_stain_pixels SHOT.png --pigment ink [--from-x X] [--baseline BASE.png]
//                            [--min-more N] [--max-baseline M]
//
// A pixel counts when its chroma (colour minus its grey mean) is at least
// 0.06 long and points within 25° of the chroma of the pigment's stain colour
// at 1 kg/m² (docs/rendering.md, stain_color.h); shading scales a colour, so
// it keeps that direction. Only columns x >= X (the 3D view) are counted.
// Exit 0 when the shot has at least N more such pixels than the baseline and
// the baseline at most M; prints both counts.
#include <blot/engine/image.h>
#include <blot/engine/stain_color.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <string>

namespace {

long countHue(const blot::engine::Image& image, const Eigen::Vector3d& hue, int fromX) {
  long count = 0;
  for (int y = 0; y < image.height(); ++y)
    for (int x = fromX; x < image.width(); ++x) {
      const auto p = image.pixel(x, y);
      Eigen::Vector3d c(p.r / 255.0, p.g / 255.0, p.b / 255.0);
      c.array() -= c.mean();
      if (c.norm() >= 0.06 && c.normalized().dot(hue) >= std::cos(25.0 * M_PI / 180.0)) ++count;
    }
  return count;
}

long number(const char* text, const char* option) {
  char* end = nullptr;
  const long v = std::strtol(text, &end, 10);
  if (end == text || *end != '\0' || v < 0) {
    std::fprintf(stderr, "blot_viewer_stain_pixels: %s: '%s' is not a whole number >= 0\n", option, text);
    std::exit(2);
  }
  return v;
}

}  // namespace

int main(int argc, char** argv) {
  std::string shot, baseline, pigment = "ink";
  long fromX = 0, minMore = 1, maxBaseline = -1;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    const bool hasValue = i + 1 < argc;
    if (a == "--pigment" && hasValue) pigment = argv[++i];
    else if (a == "--baseline" && hasValue) baseline = argv[++i];
    else if (a == "--from-x" && hasValue) fromX = number(argv[++i], "--from-x");
    else if (a == "--min-more" && hasValue) minMore = number(argv[++i], "--min-more");
    else if (a == "--max-baseline" && hasValue) maxBaseline = number(argv[++i], "--max-baseline");
    else if (shot.empty() && a[0] != '-') shot = a;
    else {
      std::fprintf(stderr, "blot_viewer_stain_pixels: unexpected argument '%s'\n", a.c_str());
      return 2;
    }
  }
  if (shot.empty()) {
    std::fprintf(stderr, "usage: blot_viewer_stain_pixels SHOT.png --pigment NAME [--from-x X] [--baseline BASE.png] "
                         "[--min-more N] [--max-baseline M]\n");
    return 2;
  }
  try {
    const auto mapping = blot::engine::stainColorMapping(blot::engine::pigmentPresetFromName(pigment));
    const Eigen::Array3d stain = blot::engine::stainColor(mapping, 0, 1.0, 0, 0);
    Eigen::Vector3d hue = stain.matrix();
    hue.array() -= hue.mean();
    hue.normalize();
    const long inShot = countHue(blot::engine::readPng(shot), hue, static_cast<int>(fromX));
    const long inBase = baseline.empty() ? 0 : countHue(blot::engine::readPng(baseline), hue, static_cast<int>(fromX));
    std::printf("%s pixels: %ld in %s, %ld in %s\n", pigment.c_str(), inShot, shot.c_str(), inBase,
                baseline.empty() ? "(no baseline)" : baseline.c_str());
    bool ok = true;
    if (inShot - inBase < minMore) {
      std::printf("FAIL: %ld more than the baseline, expected at least %ld\n", inShot - inBase, minMore);
      ok = false;
    }
    if (maxBaseline >= 0 && inBase > maxBaseline) {
      std::printf("FAIL: %ld in the baseline, expected at most %ld\n", inBase, maxBaseline);
      ok = false;
    }
    return ok ? 0 : 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "blot_viewer_stain_pixels: %s\n", e.what());
    return 2;
  }
}
