#pragma once
/// The one whole-file read of every loader (meshes, weave patterns, scenes,
/// state files, checkpoint records), with a stated byte budget per kind of
/// file, so that no input makes a loader allocate more than its budget.
#include <cstddef>
#include <stdexcept>
#include <string>

namespace blot::stain {

/// Byte budgets of the loaders (docs/reliability.md, "Limits").
inline constexpr std::size_t kMeshFileByteLimit = std::size_t(1) << 30;      ///< OBJ/PLY/OFF: 1 GiB
inline constexpr std::size_t kJsonFileByteLimit = std::size_t(16) << 20;     ///< scene and pattern JSON: 16 MiB
inline constexpr std::size_t kStateFileByteLimit = std::size_t(2) << 30;     ///< engine state files: 2 GiB
inline constexpr std::size_t kRecordFileByteLimit = std::size_t(64) << 10;   ///< checkpoint.json: 64 KiB
/// A mesh read from a stream (a named pipe, a link to a device such as
/// /dev/zero): its size is not known before it is read and the text is held
/// whole, so an endless device would take kMeshFileByteLimit (and a doubling
/// of the buffer) before the refusal. A larger mesh comes from a regular file.
inline constexpr std::size_t kMeshStreamByteLimit = std::size_t(64) << 20;  ///< 64 MiB

/// A read that failed: the message starts with the path.
struct FileReadError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

/// The whole content of `path`, refusing anything larger than `maxBytes`
/// before reading it: a regular file by its size (stat), anything else (a
/// pipe, /dev/zero, a terminal) after reading past min(maxBytes,
/// maxStreamBytes) bytes, the limit its message then names.
/// Throws FileReadError "<path>: cannot open <what>: <errno text>", "<path>:
/// <what> is N bytes, more than the limit of M bytes", "<path>: <what> has
/// more than the limit of M bytes (not a regular file: ...)", "<path>: <what>
/// is a directory", or "<path>: cannot read <what>: <errno text>".
std::string readFileBounded(const std::string& path, std::size_t maxBytes, const std::string& what,
                            std::size_t maxStreamBytes = static_cast<std::size_t>(-1));

}  // namespace blot::stain
