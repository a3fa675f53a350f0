// The difftrans command: subcommands in the manner of git (difftrans evaluate,
// difftrans info, ...). Adding a subcommand: a file difftrans/NAME.cpp that
// defines difftrans::cli::add_NAME(CLI::App&), and one X(NAME) line below.
#include "command.hpp"
#include "long_run.hpp"

#include <exception>
#include <string>

#define DIFFTRANS_COMMANDS(X) \
  X(synth)                    \
  X(render)                   \
  X(relight)                  \
  X(reconstruct)              \
  X(evaluate)                 \
  X(info)                     \
  X(shape)                    \
  X(export)                   \
  X(degrade)                  \
  X(report)

namespace difftrans::cli {
#define DIFFTRANS_DECLARE(name) void add_##name(CLI::App& app);
DIFFTRANS_COMMANDS(DIFFTRANS_DECLARE)
#undef DIFFTRANS_DECLARE
}  // namespace difftrans::cli

int main(int argc, char** argv) {
  CLI::App app{"difftrans: differentiable rendering of transparent objects.\n"
               "Run 'difftrans SUBCOMMAND --help' for a subcommand's options."};
  app.name("difftrans");
  app.require_subcommand(1);
#define DIFFTRANS_ADD(name) difftrans::cli::add_##name(app);
  DIFFTRANS_COMMANDS(DIFFTRANS_ADD)
#undef DIFFTRANS_ADD
  try {
    app.parse(argc, argv);  // runs the chosen subcommand's callback
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  } catch (const difftrans::cli::Interrupted& e) {
    difftrans::cli::progress(std::string("difftrans: ") + e.what());
    return 128 + e.signal;  // the shell's convention for "ended by signal N"
  } catch (const std::exception& e) {
    difftrans::cli::clear_status_line();
    std::cerr << "difftrans: error: " << e.what() << std::endl;
    return 1;
  }
  return 0;
}
