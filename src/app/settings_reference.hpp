#pragma once
// The configuration reference (docs/configuration.md): every key of every table, in the order
// of the one settings list (visit_settings), with its type, built-in default, allowed values and
// the comment configs/quickstart.toml (the built-in defaults, compiled in) gives it. Printed by
// `causaldrive config --reference`; a test compares the checked-in page with it.
#include <string>

namespace cd {

std::string settings_reference_markdown();

}  // namespace cd
