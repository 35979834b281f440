// How much a command says on stderr (`talus --quiet`, `--verbose`;
// docs/cli.md). Errors and warnings are always said.
#pragma once

namespace talus {

enum class Verbosity {
    quiet,   // errors and warnings only
    normal,  // and what a run does: its plan, stages, progress, summary
    verbose, // and every output and checkpoint, the plugins loaded, every plugin message
};

} // namespace talus
