// The PLY reader: header parser, layout, ASCII and binary little-endian
// sources sharing one element loop.
#include "mesh_text.h"

#include <algorithm>
#include <climits>
#include <cstdint>
#include <cstring>
#include <utility>

namespace blot::stain::detail {
namespace {

/// Most elements a header may declare, and properties per element: far past
/// what meshes carry (scanners write a few dozen vertex properties).
constexpr std::size_t kMaxPlyElements = 64;
constexpr std::size_t kMaxPlyProperties = 256;

// ---------------------------------------------------------------------------
// PLY

enum class PlyType { Int8, UInt8, Int16, UInt16, Int32, UInt32, Float32, Float64 };

bool plyTypeFromName(string_view name, PlyType& type) {
  static constexpr std::pair<const char*, PlyType> names[] = {
      {"char", PlyType::Int8},      {"int8", PlyType::Int8},       {"uchar", PlyType::UInt8},
      {"uint8", PlyType::UInt8},    {"short", PlyType::Int16},     {"int16", PlyType::Int16},
      {"ushort", PlyType::UInt16},  {"uint16", PlyType::UInt16},   {"int", PlyType::Int32},
      {"int32", PlyType::Int32},    {"uint", PlyType::UInt32},     {"uint32", PlyType::UInt32},
      {"float", PlyType::Float32},  {"float32", PlyType::Float32}, {"double", PlyType::Float64},
      {"float64", PlyType::Float64}};
  for (const auto& [typeName, value] : names) {
    if (name == typeName) {
      type = value;
      return true;
    }
  }
  return false;
}

size_t plyTypeSize(PlyType type) {
  switch (type) {
    case PlyType::Int8:
    case PlyType::UInt8:
      return 1;
    case PlyType::Int16:
    case PlyType::UInt16:
      return 2;
    case PlyType::Int32:
    case PlyType::UInt32:
    case PlyType::Float32:
      return 4;
    case PlyType::Float64:
      return 8;
  }
  return 0;
}

bool plyTypeIsInteger(PlyType type) { return type != PlyType::Float32 && type != PlyType::Float64; }

struct PlyProperty {
  std::string name;
  PlyType type = PlyType::Float32;  ///< Item type for lists.
  bool isList = false;
  PlyType countType = PlyType::UInt8;
};

struct PlyElement {
  std::string name;
  long long count = 0;
  std::vector<PlyProperty> properties;
};

struct PlyHeader {
  bool binary = false;
  std::vector<PlyElement> elements;
  size_t dataOffset = 0;  ///< Byte offset of the first data byte.
  int headerLines = 0;    ///< Lines up to and including end_header.
};

/// Which element and property indices hold the data we read (-1: absent).
struct PlyLayout {
  int vertexElement = -1, faceElement = -1;
  int x = -1, y = -1, z = -1, u = -1, v = -1;
  int indices = -1, label = -1;
};

PlyHeader parsePlyHeader(string_view text, const std::string& path) {
  PlyHeader header;
  LineReader lines(text);
  std::vector<string_view> tokens;
  string_view line;
  const auto bad = [&](const std::string& what) {
    fail(path, "bad PLY header (" + lineText(lines.lineNumber()) + "): " + what);
  };
  if (!lines.next(line)) bad("file is empty");
  splitTokens(line, '\0', tokens);
  if (tokens.size() != 1 || tokens[0] != "ply") bad("first line must be 'ply'");
  bool haveFormat = false;
  while (true) {
    if (!lines.next(line)) fail(path, "bad PLY header: no 'end_header' line");
    splitTokens(line, '\0', tokens);
    if (tokens.empty()) continue;
    const string_view keyword = tokens[0];
    if (keyword == "comment" || keyword == "obj_info") continue;
    if (keyword == "end_header") break;
    if (keyword == "format") {
      if (tokens.size() != 3) bad("expected 'format <ascii|binary_little_endian> 1.0'");
      if (tokens[1] == "binary_big_endian") {
        fail(path, lineText(lines.lineNumber()) +
                       ": binary_big_endian PLY is not supported; convert the file to "
                       "binary_little_endian or ascii");
      }
      if (tokens[1] != "ascii" && tokens[1] != "binary_little_endian")
        bad("unknown format " + quoted(tokens[1]));
      if (tokens[2] != "1.0") bad("unsupported PLY version " + quoted(tokens[2]));
      header.binary = tokens[1] != "ascii";
      haveFormat = true;
    } else if (keyword == "element") {
      long long count = 0;
      if (tokens.size() != 3 || !parseInteger(tokens[2], count) || count < 0 || count > INT_MAX)
        bad("expected 'element <name> <count>' with a count in [0, 2^31)");
      // Bounded, so the duplicate checks stay cheap: 300,000 empty elements
      // in a 5 MB header took 54 s.
      if (header.elements.size() == kMaxPlyElements)
        bad("more than " + std::to_string(kMaxPlyElements) +
            " elements declared (a mesh needs 'vertex' and 'face'; this reader takes at most " +
            std::to_string(kMaxPlyElements) + ")");
      for (const auto& earlier : header.elements)
        if (earlier.name == tokens[1]) bad("element " + quoted(tokens[1]) + " declared twice");
      header.elements.push_back({std::string(tokens[1]), count, {}});
    } else if (keyword == "property") {
      if (header.elements.empty()) bad("property before any element");
      if (header.elements.back().properties.size() == kMaxPlyProperties)
        bad("element " + quoted(header.elements.back().name) + " declares more than " +
            std::to_string(kMaxPlyProperties) + " properties (this reader takes at most " +
            std::to_string(kMaxPlyProperties) + ")");
      PlyProperty property;
      if (tokens.size() == 5 && tokens[1] == "list") {
        property.isList = true;
        if (!plyTypeFromName(tokens[2], property.countType) ||
            !plyTypeIsInteger(property.countType))
          bad("list count type " + quoted(tokens[2]) + " is not an integer type");
        if (!plyTypeFromName(tokens[3], property.type)) bad("unknown type " + quoted(tokens[3]));
        property.name = std::string(tokens[4]);
      } else if (tokens.size() == 3) {
        if (!plyTypeFromName(tokens[1], property.type)) bad("unknown type " + quoted(tokens[1]));
        property.name = std::string(tokens[2]);
      } else {
        bad("expected 'property <type> <name>' or 'property list <type> <type> <name>'");
      }
      for (const PlyProperty& earlier : header.elements.back().properties)
        if (earlier.name == property.name)
          bad("element " + quoted(header.elements.back().name) + " declares property " + quoted(property.name) +
              " twice");
      header.elements.back().properties.push_back(std::move(property));
    } else {
      bad("unknown keyword " + quoted(keyword));
    }
  }
  if (!haveFormat) fail(path, "bad PLY header: no 'format' line");
  header.dataOffset = lines.offset();
  header.headerLines = lines.lineNumber();
  return header;
}

PlyLayout plyLayout(const PlyHeader& header, const std::string& path) {
  PlyLayout layout;
  const auto bad = [&](const std::string& what) { fail(path, "bad PLY header: " + what); };
  for (size_t e = 0; e < header.elements.size(); ++e) {
    const std::string& name = header.elements[e].name;
    if (name == "vertex" && layout.vertexElement < 0) layout.vertexElement = static_cast<int>(e);
    if (name == "face" && layout.faceElement < 0) layout.faceElement = static_cast<int>(e);
  }
  if (layout.vertexElement < 0) bad("no 'vertex' element");
  if (layout.faceElement < 0) bad("no 'face' element");

  const auto find = [](const PlyElement& element, const char* name) {
    for (size_t p = 0; p < element.properties.size(); ++p)
      if (element.properties[p].name == name) return static_cast<int>(p);
    return -1;
  };
  const PlyElement& vertex = header.elements[static_cast<size_t>(layout.vertexElement)];
  int* const coordinates[3] = {&layout.x, &layout.y, &layout.z};
  const char* const coordinateNames[3] = {"x", "y", "z"};
  for (int k = 0; k < 3; ++k) {
    *coordinates[k] = find(vertex, coordinateNames[k]);
    if (*coordinates[k] < 0)
      bad(std::string("element 'vertex' has no property '") + coordinateNames[k] + "'");
  }
  const char* const uvNames[4][2] = {
      {"u", "v"}, {"s", "t"}, {"texture_u", "texture_v"}, {"texture_s", "texture_t"}};
  for (const auto& names : uvNames) {
    const int u = find(vertex, names[0]), v = find(vertex, names[1]);
    if (u >= 0 && v >= 0) {
      layout.u = u;
      layout.v = v;
      break;
    }
  }
  for (const int p : {layout.x, layout.y, layout.z, layout.u, layout.v}) {
    if (p >= 0 && vertex.properties[static_cast<size_t>(p)].isList)
      bad("vertex property '" + vertex.properties[static_cast<size_t>(p)].name + "' is a list");
  }

  const PlyElement& face = header.elements[static_cast<size_t>(layout.faceElement)];
  layout.indices = find(face, "vertex_indices");
  if (layout.indices < 0) layout.indices = find(face, "vertex_index");
  if (layout.indices < 0)
    bad("element 'face' has no list property 'vertex_indices' or 'vertex_index'");
  const PlyProperty& indices = face.properties[static_cast<size_t>(layout.indices)];
  if (!indices.isList || !plyTypeIsInteger(indices.type))
    bad("face property '" + indices.name + "' must be a list of an integer type");
  layout.label = find(face, "label");
  if (layout.label >= 0) {
    const PlyProperty& label = face.properties[static_cast<size_t>(layout.label)];
    if (label.isList || !plyTypeIsInteger(label.type))
      bad("face property 'label' must be a scalar integer");
  }
  return layout;
}

std::string elementText(const PlyElement& element, long long index) {
  return element.name + " " + std::to_string(index);
}

/// ASCII PLY data: one element instance per line.
class PlyAsciiSource {
 public:
  /// Every element instance is a line, so a count is bounded by the file.
  static constexpr bool kElementsTakeSpace = true;
  PlyAsciiSource(string_view data, int linesBefore, const std::string& path)
      : lines_(data), linesBefore_(linesBefore), path_(path) {}

  void beginElement(const PlyElement& element, long long index) {
    string_view text;
    do {
      if (!lines_.next(text)) {
        fail(path_, "file ends after " + std::to_string(index) + " of the " +
                        std::to_string(element.count) + " '" + element.name +
                        "' elements declared in the header (" + lineText(line()) + ")");
      }
      splitTokens(text, '\0', tokens_);
    } while (tokens_.empty());
    next_ = 0;
  }

  double readReal(const PlyElement& element, long long index, const PlyProperty& property) {
    const string_view token = take(element, index, property);
    double value = 0.0;
    if (!parseDouble(token, value)) {
      fail(path_, lineText(line()) + ": " + elementText(element, index) + ", property '" +
                      property.name + "': expected a number, got " + quoted(token));
    }
    return value;
  }

  long long readInteger(const PlyElement& element, long long index, const PlyProperty& property) {
    const string_view token = take(element, index, property);
    long long value = 0;
    if (!parseInteger(token, value)) {
      fail(path_, lineText(line()) + ": " + elementText(element, index) + ", property '" +
                      property.name + "': expected an integer, got " + quoted(token));
    }
    return value;
  }

  void endElement(const PlyElement& element, long long index) {
    if (next_ < tokens_.size()) {
      fail(path_, lineText(line()) + ": " + elementText(element, index) + " has " +
                      std::to_string(tokens_.size()) +
                      " values, more than its properties declare " +
                      "(do the counts in the header match the data?)");
    }
  }

  void finish(const PlyHeader& header) {
    string_view text;
    while (lines_.next(text)) {
      splitTokens(text, '\0', tokens_);
      if (!tokens_.empty()) {
        std::string counts;
        for (const PlyElement& element : header.elements)
          counts += (counts.empty() ? "" : ", ") + std::to_string(element.count) + " '" +
                    element.name + "'";
        fail(path_, lineText(line()) + ": data after the last element the header declares (" +
                        counts + "); the counts in the header do not match the data");
      }
    }
  }

  /// 1-based line in the file of the current element.
  int line() const { return linesBefore_ + lines_.lineNumber(); }

 private:
  string_view take(const PlyElement& element, long long index, const PlyProperty& property) {
    if (next_ >= tokens_.size()) {
      fail(path_, lineText(line()) + ": " + elementText(element, index) +
                      " has too few values (property '" + property.name + "' is missing)");
    }
    return tokens_[next_++];
  }

  LineReader lines_;
  int linesBefore_;
  const std::string& path_;
  std::vector<string_view> tokens_;
  size_t next_ = 0;
};

/// Binary little-endian PLY data, decoded byte by byte so that the host's
/// byte order does not matter.
class PlyBinarySource {
 public:
  /// An element without properties holds no bytes.
  static constexpr bool kElementsTakeSpace = false;
  PlyBinarySource(string_view data, const std::string& path) : data_(data), path_(path) {}

  void beginElement(const PlyElement&, long long) {}
  void endElement(const PlyElement&, long long) {}
  int line() const { return 0; }

  double readReal(const PlyElement& element, long long index, const PlyProperty& property,
                  PlyType type) {
    const std::uint64_t bits = load(element, index, property, plyTypeSize(type));
    switch (type) {
      case PlyType::Float32: {
        const auto narrow = static_cast<std::uint32_t>(bits);
        float value = 0.0f;
        std::memcpy(&value, &narrow, sizeof value);
        return value;
      }
      case PlyType::Float64: {
        double value = 0.0;
        std::memcpy(&value, &bits, sizeof value);
        return value;
      }
      default:
        return static_cast<double>(toInteger(bits, type));
    }
  }

  long long readInteger(const PlyElement& element, long long index, const PlyProperty& property,
                        PlyType type) {
    return toInteger(load(element, index, property, plyTypeSize(type)), type);
  }

  void finish(const PlyHeader&) {
    if (pos_ != data_.size()) {
      fail(path_, std::to_string(data_.size() - pos_) +
                      " bytes of binary data after the last element the header declares; the "
                      "counts in the header do not match the data");
    }
  }

 private:
  static long long toInteger(std::uint64_t bits, PlyType type) {
    switch (type) {
      case PlyType::Int8:
        return static_cast<std::int8_t>(bits);
      case PlyType::UInt8:
        return static_cast<std::uint8_t>(bits);
      case PlyType::Int16:
        return static_cast<std::int16_t>(bits);
      case PlyType::UInt16:
        return static_cast<std::uint16_t>(bits);
      case PlyType::Int32:
        return static_cast<std::int32_t>(bits);
      case PlyType::UInt32:
        return static_cast<std::uint32_t>(bits);
      default:
        return 0;  // float types never reach here (checked in the header)
    }
  }

  std::uint64_t load(const PlyElement& element, long long index, const PlyProperty& property,
                     size_t size) {
    if (data_.size() - pos_ < size) {
      fail(path_, "truncated binary data: the file ends inside " + elementText(element, index) +
                      " of " + std::to_string(element.count) + " (property '" + property.name +
                      "', byte " + std::to_string(pos_) + " of the data)");
    }
    std::uint64_t bits = 0;
    for (size_t b = 0; b < size; ++b)
      bits |= static_cast<std::uint64_t>(static_cast<unsigned char>(data_[pos_ + b])) << (8 * b);
    pos_ += size;
    return bits;
  }

  string_view data_;
  const std::string& path_;
  size_t pos_ = 0;
};

// The two sources share one element loop; the type argument only matters to
// the binary source (ASCII tokens carry their own spelling).
double readPlyReal(PlyAsciiSource& s, const PlyElement& e, long long i, const PlyProperty& p,
                   PlyType) {
  return s.readReal(e, i, p);
}
double readPlyReal(PlyBinarySource& s, const PlyElement& e, long long i, const PlyProperty& p,
                   PlyType t) {
  return s.readReal(e, i, p, t);
}
long long readPlyInteger(PlyAsciiSource& s, const PlyElement& e, long long i, const PlyProperty& p,
                         PlyType) {
  return s.readInteger(e, i, p);
}
long long readPlyInteger(PlyBinarySource& s, const PlyElement& e, long long i, const PlyProperty& p,
                         PlyType t) {
  return s.readInteger(e, i, p, t);
}

template <class Source>
long long readPlyListCount(Source& source, const PlyElement& element, long long index,
                           const PlyProperty& property, const std::string& path) {
  const long long count = readPlyInteger(source, element, index, property, property.countType);
  if (count < 0) {
    fail(path, (source.line() > 0 ? lineText(source.line()) + ": " : std::string()) +
                   elementText(element, index) + ", property '" + property.name +
                   "': negative list length " + std::to_string(count));
  }
  return count;
}

template <class Source>
TriangleMesh readPlyBody(Source& source, const PlyHeader& header, const PlyLayout& layout,
                         size_t dataBytes, const std::string& path, ElementOrigins& origins) {
  const auto& vertexElement = header.elements[static_cast<size_t>(layout.vertexElement)];
  const long long vertexCount = vertexElement.count;
  const bool hasUVs = layout.u >= 0;
  const bool hasLabels = layout.label >= 0;
  // Reserve no more than the data could hold, so a corrupt count cannot ask for gigabytes.
  const auto capped = [&](long long count) {
    return static_cast<size_t>(
        std::min<long long>(count, static_cast<long long>(dataBytes / 2 + 1)));
  };
  std::vector<double> positions, uvs;
  std::vector<int> triangles, labels, corners;
  positions.reserve(3 * capped(vertexCount));
  if (hasUVs) uvs.reserve(2 * capped(vertexCount));
  triangles.reserve(3 * capped(header.elements[static_cast<size_t>(layout.faceElement)].count));

  for (size_t e = 0; e < header.elements.size(); ++e) {
    const PlyElement& element = header.elements[e];
    const bool isVertex = static_cast<int>(e) == layout.vertexElement;
    const bool isFace = static_cast<int>(e) == layout.faceElement;
    // A binary element without properties is nothing but its count: read as
    // such, not instance by instance (a 300-byte file declaring 9e8 of them
    // took seconds; fuzz_mesh_ply, docs/reliability.md finding 11).
    if (!Source::kElementsTakeSpace && element.properties.empty()) continue;
    for (long long i = 0; i < element.count; ++i) {
      source.beginElement(element, i);
      double xyz[3] = {0.0, 0.0, 0.0}, uv[2] = {0.0, 0.0};
      int label = 0;
      for (size_t p = 0; p < element.properties.size(); ++p) {
        const PlyProperty& property = element.properties[p];
        const int pi = static_cast<int>(p);
        if (isFace && pi == layout.indices) {
          const long long count = readPlyListCount(source, element, i, property, path);
          if (count < 3) {
            fail(path, (source.line() > 0 ? lineText(source.line()) + ": " : std::string()) +
                           "face " + std::to_string(i) + " has " + std::to_string(count) +
                           " corners, faces need at least 3");
          }
          corners.clear();
          for (long long k = 0; k < count; ++k) {
            const long long index = readPlyInteger(source, element, i, property, property.type);
            if (index < 0 || index >= vertexCount) {
              fail(path,
                   "face " + std::to_string(i) +
                       (source.line() > 0 ? " (" + lineText(source.line()) + ")" : std::string()) +
                       ": vertex index " + std::to_string(index) + " out of range [0, " +
                       std::to_string(vertexCount - 1) + "]");
            }
            corners.push_back(static_cast<int>(index));
          }
        } else if (property.isList) {
          const long long count = readPlyListCount(source, element, i, property, path);
          for (long long k = 0; k < count; ++k)
            readPlyReal(source, element, i, property, property.type);
        } else if (isFace && pi == layout.label) {
          const long long value = readPlyInteger(source, element, i, property, property.type);
          if (value < INT_MIN || value > INT_MAX)
            fail(path, "face " + std::to_string(i) + ": label " + std::to_string(value) +
                           " out of int range");
          label = static_cast<int>(value);
        } else {
          const double value = readPlyReal(source, element, i, property, property.type);
          if (isVertex) {
            if (pi == layout.x) xyz[0] = value;
            if (pi == layout.y) xyz[1] = value;
            if (pi == layout.z) xyz[2] = value;
            if (pi == layout.u) uv[0] = value;
            if (pi == layout.v) uv[1] = value;
          }
        }
      }
      source.endElement(element, i);
      if (isVertex) {
        positions.insert(positions.end(), xyz, xyz + 3);
        if (hasUVs) uvs.insert(uvs.end(), uv, uv + 2);
        if (source.line() > 0) origins.vertexLines.push_back(source.line());
      } else if (isFace) {
        appendPolygon(path, corners, positions, static_cast<int>(i), source.line(), hasLabels, label, triangles,
                      labels, origins);
      }
    }
  }
  source.finish(header);
  return assembleMesh(positions, triangles, std::move(labels), uvs);
}

}  // namespace

TriangleMesh readPly(const std::string& text, const std::string& path, ElementOrigins& origins) {
  const PlyHeader header = parsePlyHeader(text, path);
  const PlyLayout layout = plyLayout(header, path);
  const string_view data = string_view(text).substr(header.dataOffset);
  if (header.binary) {
    PlyBinarySource source(data, path);
    return readPlyBody(source, header, layout, data.size(), path, origins);
  }
  PlyAsciiSource source(data, header.headerLines, path);
  return readPlyBody(source, header, layout, data.size(), path, origins);
}

}  // namespace blot::stain::detail
