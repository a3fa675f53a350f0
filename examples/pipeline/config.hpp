// One list of fields per stage configuration. Every config struct of the
// pipeline (EnvironmentConfig, Stage1Config, Stage2Config) has a static
// `fields(config, visit)` that calls visit(Field, member) once per setting, in
// the order a person reads them; from that one list the command registers its
// options (examples/difftrans/config_options.hpp), the JSON record writes and
// reads the settings back (write_fields / read_fields below) and the log
// describes a run (describe_fields). A setting added to the list appears in all
// four; nothing else names it.
//
// Member types: bool, int, std::uint64_t, float, double, std::string, Vec3f
// (record only: no option), enums with an `enum_names(E)` overload (found by
// argument-dependent lookup: the names in the enum's order), and nested
// structs with their own static fields() (a JSON object of their own).
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include "difftrans/ad/glm.hpp"
#include "difftrans/io/json.hpp"

namespace difftrans::pipeline {

struct Field {
  const char* key;   // the name in reconstruct.json (and in --weights NAME=VALUE for nested groups)
  const char* flag;  // the command-line option, "" for none (set through a composite option, or fixed)
  const char* help;
  double min = -std::numeric_limits<double>::infinity();  // accepted range of a number
  double max = std::numeric_limits<double>::infinity();
};

namespace detail {

template <class T, class = void>
struct has_fields : std::false_type {};
template <class T>
struct has_fields<T, std::void_t<decltype(T::fields(std::declval<T&>(), std::declval<void (*)(const Field&, int&)>()))>>
    : std::true_type {};

template <class E>
std::string enum_name(E e) {
  const auto& names = enum_names(E{});
  const std::size_t i = std::size_t(e);
  return i < names.size() ? names[i] : std::to_string(int(e));
}

template <class E>
E enum_from_name(const std::string& name, const std::string& where) {
  const auto& names = enum_names(E{});
  std::string known;
  for (std::size_t i = 0; i < names.size(); ++i) {
    if (name == names[i]) return E(i);
    known += (i ? ", " : "") + std::string(names[i]);
  }
  throw std::runtime_error(where + ": '" + name + "' is not one of " + known);
}

}  // namespace detail

// Writes every field of `config` into `j` (a JSON object).
template <class Config>
void write_fields(const Config& config, io::Json& j) {
  Config::fields(config, [&](const Field& f, const auto& value) {
    using T = std::decay_t<decltype(value)>;
    if constexpr (detail::has_fields<T>::value) {
      io::Json sub = io::Json::object();
      write_fields(value, sub);
      j[f.key] = sub;
    } else if constexpr (std::is_enum_v<T>) {
      j[f.key] = detail::enum_name(value);
    } else if constexpr (std::is_same_v<T, Vec3f>) {
      j[f.key] = {value.x, value.y, value.z};
    } else {
      j[f.key] = value;
    }
  });
}

// Reads the fields present in `j` into `config` (absent ones keep their
// value); a value of the wrong type or out of range throws naming `where` and
// the key.
template <class Config>
void read_fields(const io::Json& j, Config& config, const std::string& where) {
  if (!j.is_object()) throw std::runtime_error(where + ": not a JSON object");
  Config::fields(config, [&](const Field& f, auto& value) {
    using T = std::decay_t<decltype(value)>;
    if (!j.contains(f.key)) return;
    const io::Json& v = j[f.key];
    const std::string at = where + "." + f.key;
    try {
      if constexpr (detail::has_fields<T>::value) {
        read_fields(v, value, at);
      } else if constexpr (std::is_enum_v<T>) {
        value = detail::enum_from_name<T>(v.get<std::string>(), at);
      } else if constexpr (std::is_same_v<T, Vec3f>) {
        if (!v.is_array() || v.size() != 3) throw std::runtime_error(at + ": expected [x, y, z]");
        value = Vec3f(v[0].get<float>(), v[1].get<float>(), v[2].get<float>());
      } else if constexpr (std::is_same_v<T, bool> || std::is_same_v<T, std::string>) {
        value = v.get<T>();
      } else if constexpr (std::is_same_v<T, std::vector<float>>) {
        if (!v.is_array()) throw std::runtime_error(at + ": expected a list of numbers");
        std::vector<float> list;
        for (const io::Json& x : v) {
          if (!x.is_number() || !(x.get<double>() >= f.min && x.get<double>() <= f.max))
            throw std::runtime_error(at + ": " + io::json_excerpt(x) + " is not a number in [" +
                                     io::Json(f.min).dump() + ", " + io::Json(f.max).dump() + "]");
          list.push_back(x.get<float>());
        }
        value = std::move(list);
      } else {
        if (!v.is_number()) throw std::runtime_error(at + ": expected a number");
        const double x = v.get<double>();
        if (!(x >= f.min && x <= f.max))
          throw std::runtime_error(at + ": " + io::json_excerpt(v) + " lies outside [" + io::Json(f.min).dump() + ", " +
                                   io::Json(f.max).dump() + "]");
        value = v.get<T>();
      }
    } catch (const io::Json::exception&) {
      throw std::runtime_error(at + ": " + io::json_excerpt(v) + " is not of the setting's type");
    }
  });
}

// "key = value" per field, nested groups as "group.key", one per line.
template <class Config>
std::string describe_fields(const Config& config, const std::string& prefix = "") {
  std::ostringstream out;
  Config::fields(config, [&](const Field& f, const auto& value) {
    using T = std::decay_t<decltype(value)>;
    if constexpr (detail::has_fields<T>::value) {
      out << describe_fields(value, prefix + f.key + ".");
    } else if constexpr (std::is_enum_v<T>) {
      out << prefix << f.key << " = " << detail::enum_name(value) << "\n";
    } else if constexpr (std::is_same_v<T, Vec3f>) {
      out << prefix << f.key << " = (" << value.x << ", " << value.y << ", " << value.z << ")\n";
    } else if constexpr (std::is_same_v<T, bool>) {
      out << prefix << f.key << " = " << (value ? "true" : "false") << "\n";
    } else if constexpr (std::is_same_v<T, std::vector<float>>) {
      out << prefix << f.key << " = [";
      for (std::size_t i = 0; i < value.size(); ++i) out << (i ? ", " : "") << value[i];
      out << "]\n";
    } else {
      out << prefix << f.key << " = " << value << "\n";
    }
  });
  return out.str();
}

}  // namespace difftrans::pipeline
