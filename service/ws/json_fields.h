#pragma once
// Checked reading of JSON fields from the wire (docs/WEBSOCKET.md section 2):
// every field's presence, type and range is checked, and every array's
// length against its limit before anything is sized from it. A problem
// throws WsProtocolError with a stable code and one line naming the field.

#include <cstddef>
#include <cstdint>
#include <nlohmann/json.hpp>
#include <stdexcept>
#include <string>

namespace sweptccd::ws {

/// The largest integer magnitude exchanged (2^53 - 1): exactly representable
/// as a JavaScript number.
inline constexpr int64_t kMaxSafeInteger = (int64_t{1} << 53) - 1;

/// A refused message: `code` is one of docs/WEBSOCKET.md's error codes.
class WsProtocolError : public std::runtime_error {
 public:
  WsProtocolError(std::string code, const std::string& message)
      : std::runtime_error(message), code_(std::move(code)) {}
  const std::string& code() const { return code_; }

 private:
  std::string code_;
};

/// Throws WsProtocolError("bad_message", "<where>: <problem>").
[[noreturn]] void BadMessage(const std::string& where, const std::string& problem);

/// One JSON value read as a field at `where` (a path such as
/// "join_request.a[3]" used in errors). Thread-safe (pure).
int64_t IntAt(const nlohmann::json& v, const std::string& where, int64_t lo, int64_t hi);
double RealAt(const nlohmann::json& v, const std::string& where);
/// A real a peer sent: a number, or null (a non-finite value, written null).
double RealOrNullAt(const nlohmann::json& v, const std::string& where);
bool BoolAt(const nlohmann::json& v, const std::string& where);
std::string StringAt(const nlohmann::json& v, const std::string& where, size_t max_bytes);
/// An array of at most `max_length` elements (checked before the caller
/// allocates for them).
const nlohmann::json& ArrayAt(const nlohmann::json& v, const std::string& where, size_t max_length);
/// An array of exactly `n` reals into `out[0..n)`.
void RealsAt(const nlohmann::json& v, const std::string& where, size_t n, double* out,
             bool allow_null = false);

/// The fields of one JSON object.
class Fields {
 public:
  /// Throws bad_message unless `v` is an object.
  Fields(const nlohmann::json& v, std::string where);
  /// The field, or throws bad_message ("missing").
  const nlohmann::json& Get(const char* name) const;
  /// The field, or null when absent.
  const nlohmann::json* Find(const char* name) const;
  std::string Path(const char* name) const { return where_ + "." + name; }

  int64_t Int(const char* name, int64_t lo, int64_t hi) const {
    return IntAt(Get(name), Path(name), lo, hi);
  }
  double Real(const char* name) const { return RealAt(Get(name), Path(name)); }
  double RealOrNull(const char* name) const { return RealOrNullAt(Get(name), Path(name)); }
  bool Bool(const char* name) const { return BoolAt(Get(name), Path(name)); }
  std::string String(const char* name, size_t max_bytes) const {
    return StringAt(Get(name), Path(name), max_bytes);
  }
  const nlohmann::json& Array(const char* name, size_t max_length) const {
    return ArrayAt(Get(name), Path(name), max_length);
  }
  const std::string& where() const { return where_; }

 private:
  const nlohmann::json& v_;
  std::string where_;
};

}  // namespace sweptccd::ws
