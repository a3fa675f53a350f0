// Command-line options from a pipeline config's list of fields
// (pipeline/config.hpp): every field with a flag becomes one option of the
// subcommand, its default shown, numbers checked against the field's range,
// enums against their names, bools as flags. Nested groups add their fields'
// options too.
#pragma once

#include <cmath>
#include <string>
#include <type_traits>
#include <vector>

#include "command.hpp"

#include "pipeline/config.hpp"

namespace difftrans::cli {

template <class Config>
void add_config_options(CLI::App* cmd, Config& config, const std::string& help_prefix) {
  Config::fields(config, [&](const pipeline::Field& f, auto& value) {
    using T = std::decay_t<decltype(value)>;
    if constexpr (pipeline::detail::has_fields<T>::value) {
      add_config_options(cmd, value, help_prefix);
    } else if constexpr (std::is_same_v<T, Vec3f>) {
      // record only
    } else {
      if (f.flag[0] == '\0') return;
      const std::string help = help_prefix + f.help;
      if constexpr (std::is_same_v<T, bool>) {
        cmd->add_flag(f.flag, value, help);
      } else if constexpr (std::is_enum_v<T>) {
        std::vector<std::string> names;
        for (const char* n : enum_names(T{})) names.push_back(n);
        cmd->add_option_function<std::string>(
               f.flag, [&value, flag = std::string(f.flag)](const std::string& s) {
                 value = pipeline::detail::enum_from_name<T>(s, flag);
               },
               help)
            ->default_str(pipeline::detail::enum_name(value))
            ->check(CLI::IsMember(names));
      } else if constexpr (std::is_same_v<T, std::vector<float>>) {
        // a comma-separated list, each number in the field's range
        CLI::Option* o = cmd->add_option(f.flag, value, help)->delimiter(',')->capture_default_str();
        if (std::isfinite(f.min) && std::isfinite(f.max)) o->check(CLI::Range(float(f.min), float(f.max)));
      } else {
        CLI::Option* o = cmd->add_option(f.flag, value, help)->capture_default_str();
        if constexpr (std::is_arithmetic_v<T>)
          if (std::isfinite(f.min) && std::isfinite(f.max)) o->check(CLI::Range(T(f.min), T(f.max)));
      }
    }
  });
}

}  // namespace difftrans::cli
