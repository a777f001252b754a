// format_dom.h — step 1 of reading the batch formats (format.cpp has the
// overview and step 2): JSON text to a DOM whose errors carry lines, a field
// path's line, and the text helpers of error messages.
#pragma once

#include <cstddef>
#include <string>
#include <string_view>

#include <nlohmann/json.hpp>

namespace voxvis::detail {

using json = nlohmann::json;

/// Parses `text` into `root`, refusing duplicate keys and nesting deeper than
/// 64 levels. On error sets the line, the field path (every byte outside
/// printable ASCII written \xNN) and the message. With `want_lines`,
/// duplicate-key messages name the line of the first occurrence.
bool parse_dom(std::string_view text, json* root, bool want_lines, int* error_line,
               std::string* error_field, std::string* error_message);

/// Line of field `path` ("objects[3].radius"; "" is the document) in `text`,
/// or of its nearest parent that has one; 1 when none has.
int line_of_path(std::string_view text, std::string path);

/// A key or string value quoted for an error message: printable ASCII kept,
/// everything else escaped, long text cut.
std::string quote_text(std::string_view s, char quote = '\'');

/// "a number", "a string \"x\"", ... for "got ..." in messages.
std::string describe(const json& v);

/// "path.key", or "key" at the top.
std::string join_key(std::string_view path, std::string_view key);

/// "path[index]".
std::string join_index(std::string_view path, std::size_t index);

}  // namespace voxvis::detail
