#include "service/ws/json_fields.h"

#include <cmath>
#include <limits>

#include "msgs/text.h"

namespace sweptccd::ws {

void BadMessage(const std::string& where, const std::string& problem) {
  throw WsProtocolError("bad_message", where + ": " + problem);
}

namespace {

const char* TypeName(const nlohmann::json& v) { return v.type_name(); }

}  // namespace

int64_t IntAt(const nlohmann::json& v, const std::string& where, int64_t lo, int64_t hi) {
  int64_t x = 0;
  if (v.is_number_unsigned()) {
    const uint64_t u = v.get<uint64_t>();
    if (u > static_cast<uint64_t>(kMaxSafeInteger)) {
      BadMessage(where, "integer beyond 2^53-1");
    }
    x = static_cast<int64_t>(u);
  } else if (v.is_number_integer()) {
    x = v.get<int64_t>();
  } else {
    BadMessage(where, std::string("expected an integer, got ") + TypeName(v));
  }
  if (x < -kMaxSafeInteger || x > kMaxSafeInteger) BadMessage(where, "integer beyond 2^53-1");
  if (x < lo || x > hi) {
    BadMessage(where, std::to_string(x) + " outside [" + std::to_string(lo) + ", " +
                          std::to_string(hi) + "]");
  }
  return x;
}

double RealAt(const nlohmann::json& v, const std::string& where) {
  if (!v.is_number()) BadMessage(where, std::string("expected a number, got ") + TypeName(v));
  return v.get<double>();
}

double RealOrNullAt(const nlohmann::json& v, const std::string& where) {
  if (v.is_null()) return std::numeric_limits<double>::quiet_NaN();
  return RealAt(v, where);
}

bool BoolAt(const nlohmann::json& v, const std::string& where) {
  if (!v.is_boolean()) BadMessage(where, std::string("expected true or false, got ") + TypeName(v));
  return v.get<bool>();
}

std::string StringAt(const nlohmann::json& v, const std::string& where, size_t max_bytes) {
  if (!v.is_string()) BadMessage(where, std::string("expected a string, got ") + TypeName(v));
  const std::string& s = v.get_ref<const std::string&>();
  if (s.size() > max_bytes) {
    BadMessage(where, "string of " + std::to_string(s.size()) + " bytes, over the limit " +
                          std::to_string(max_bytes));
  }
  return s;
}

const nlohmann::json& ArrayAt(const nlohmann::json& v, const std::string& where,
                              size_t max_length) {
  if (!v.is_array()) BadMessage(where, std::string("expected an array, got ") + TypeName(v));
  if (v.size() > max_length) {
    BadMessage(where, "array of " + std::to_string(v.size()) + " elements, over the limit " +
                          std::to_string(max_length));
  }
  return v;
}

void RealsAt(const nlohmann::json& v, const std::string& where, size_t n, double* out,
             bool allow_null) {
  if (!v.is_array() || v.size() != n) {
    BadMessage(where, "expected an array of " + std::to_string(n) + " numbers");
  }
  for (size_t i = 0; i < n; ++i) {
    const std::string at = where + "[" + std::to_string(i) + "]";
    out[i] = allow_null ? RealOrNullAt(v[i], at) : RealAt(v[i], at);
  }
}

Fields::Fields(const nlohmann::json& v, std::string where) : v_(v), where_(std::move(where)) {
  if (!v_.is_object()) BadMessage(where_, std::string("expected an object, got ") + TypeName(v_));
}

const nlohmann::json& Fields::Get(const char* name) const {
  const auto it = v_.find(name);
  if (it == v_.end()) BadMessage(Path(name), "missing");
  return *it;
}

const nlohmann::json* Fields::Find(const char* name) const {
  const auto it = v_.find(name);
  return it == v_.end() ? nullptr : &*it;
}

}  // namespace sweptccd::ws
