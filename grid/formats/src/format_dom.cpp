// format_dom.cpp — step 1 of reading the batch formats: JSON text to a DOM
// with lines, and a field path's line (format.cpp has the overview).
#include "format_dom.h"

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <iterator>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "format_text.h"
#include "voxvis/types.h"

namespace voxvis::detail {
namespace {

constexpr std::size_t kMaxDepth = 64;

/// `s` with every byte outside printable ASCII written as \xNN: a field path
/// made of the input's own keys, or a JSON library message quoting the input,
/// goes on one terminal line and carries no control sequence.
std::string printable(std::string_view s) {
  static constexpr char kHex[] = "0123456789abcdef";
  std::string out;
  out.reserve(s.size());
  for (const char ch : s) {
    const auto c = static_cast<unsigned char>(ch);
    if (c >= 0x20 && c < 0x7f) {
      out += ch;
    } else {
      out += "\\x";
      out += kHex[c >> 4];
      out += kHex[c & 15];
    }
  }
  return out;
}

/// Where the lexer is: lines of the characters consumed so far.
struct LineCounter {
  int line = 1;         ///< Line of the next character.
  int column = 0;       ///< Characters consumed on the current line.
  int token_line = 1;   ///< Line of the last non-whitespace character consumed.
  int token_column = 1; ///< Its 1-based column (bytes).
};

/// A char iterator over [p, end) that reports every consumed character to a
/// LineCounter. nlohmann's iterator_input_adapter reads a character with
/// `*current` and then `std::advance(current, 1)`, so counting in operator++
/// counts exactly the characters the lexer has taken. The lexer's one-character
/// lookahead after a number is ungot inside the lexer, not in the input, so it
/// is counted; it is either adjacent to the number (same line) or whitespace,
/// which is why callbacks use the line of the last non-whitespace character:
/// that is always a character of the token just completed.
class CountingIterator {
 public:
  using iterator_category = std::input_iterator_tag;
  using value_type = char;
  using difference_type = std::ptrdiff_t;
  using pointer = const char*;
  using reference = const char&;

  CountingIterator() = default;
  CountingIterator(const char* p, LineCounter* counter) : p_(p), counter_(counter) {}

  reference operator*() const { return *p_; }
  CountingIterator& operator++() {
    const char c = *p_;
    if (c == '\n') {
      ++counter_->line;
      counter_->column = 0;
    } else {
      ++counter_->column;
      if (c != ' ' && c != '\t' && c != '\r') {
        counter_->token_line = counter_->line;
        counter_->token_column = counter_->column;
      }
    }
    ++p_;
    return *this;
  }
  CountingIterator operator++(int) {
    CountingIterator old = *this;
    ++*this;
    return old;
  }
  // nlohmann compares with !=, which C++20 rewrites into this.
  friend bool operator==(const CountingIterator& a, const CountingIterator& b) {
    return a.p_ == b.p_;
  }

 private:
  const char* p_ = nullptr;
  LineCounter* counter_ = nullptr;
};

/// SAX handler that follows field paths through a document and stops at the
/// first key or array element whose path is `target`, noting its line.
class LineFinder {
 public:
  using number_integer_t = json::number_integer_t;
  using number_unsigned_t = json::number_unsigned_t;
  using number_float_t = json::number_float_t;
  using string_t = json::string_t;
  using binary_t = json::binary_t;

  LineFinder(const LineCounter* counter, const std::string* target)
      : counter_(counter), target_(target) {}

  bool null() { return value(false, false); }
  bool boolean(bool /*v*/) { return value(false, false); }
  bool number_integer(number_integer_t /*v*/) { return value(false, false); }
  bool number_unsigned(number_unsigned_t /*v*/) { return value(false, false); }
  bool number_float(number_float_t /*v*/, const string_t& /*text*/) { return value(false, false); }
  bool string(string_t& /*v*/) { return value(false, false); }
  bool binary(binary_t& /*v*/) { return false; }
  bool start_object(std::size_t /*elements*/) { return value(true, false); }
  bool start_array(std::size_t /*elements*/) { return value(true, true); }
  bool key(string_t& k) {
    path_.resize(stack_.back().path_len);
    if (!path_.empty()) path_ += '.';
    path_ += k;
    return !match();
  }
  bool end_object() {
    stack_.pop_back();
    return true;
  }
  bool end_array() {
    stack_.pop_back();
    return true;
  }
  bool parse_error(std::size_t /*position*/, const std::string& /*token*/,
                   const json::exception& /*ex*/) {
    return false;
  }

  int line() const { return line_; }

 private:
  struct Level {
    std::size_t path_len;
    std::size_t index;
    bool is_array;
  };

  bool match() {
    if (path_ != *target_) return false;
    line_ = counter_->token_line;
    return true;
  }

  /// A value starts; members got their path from key(), elements get it here.
  bool value(bool container, bool array) {
    if (stack_.empty()) {
      path_.clear();
    } else if (stack_.back().is_array) {
      Level& top = stack_.back();
      path_.resize(top.path_len);
      path_ += '[';
      append_int(path_, top.index);
      path_ += ']';
      ++top.index;
    }
    if (match()) return false;
    if (container) stack_.push_back(Level{path_.size(), 0, array});
    return true;
  }

  const LineCounter* counter_;
  const std::string* target_;
  std::vector<Level> stack_;
  std::string path_;
  int line_ = 0;
};

/// Line of the first key or array element of `text` with field path `path`
/// ("" is the document itself); 0 when there is none.
int find_line(std::string_view text, const std::string& path) {
  LineCounter counter;
  LineFinder finder(&counter, &path);
  const CountingIterator first(text.data(), &counter);
  const CountingIterator last(text.data() + text.size(), &counter);
  json::sax_parse(first, last, &finder, json::input_format_t::json, /*strict=*/false,
                  /*ignore_comments=*/false);
  return finder.line();
}

}  // namespace

std::string quote_text(std::string_view s, char quote) {
  constexpr std::size_t kMax = 48;
  std::string out(1, quote);
  for (std::size_t i = 0; i < s.size() && i < kMax; ++i) {
    const auto c = static_cast<unsigned char>(s[i]);
    if (c == '\\' || c == static_cast<unsigned char>(quote)) {
      out += '\\';
      out += static_cast<char>(c);
    } else if (c >= 0x20 && c < 0x7f) {
      out += static_cast<char>(c);
    } else {
      static constexpr char kHex[] = "0123456789abcdef";
      out += "\\x";
      out += kHex[c >> 4];
      out += kHex[c & 15];
    }
  }
  if (s.size() > kMax) out += "...";
  out += quote;
  return out;
}

std::string describe(const json& v) {
  switch (v.type()) {
    case json::value_t::null:
      return "null";
    case json::value_t::boolean:
      return v.get<bool>() ? "true" : "false";
    case json::value_t::number_integer:
      return std::to_string(v.get<std::int64_t>());
    case json::value_t::number_unsigned:
      return std::to_string(v.get<std::uint64_t>());
    case json::value_t::number_float:
      return number_text(v.get<double>());
    case json::value_t::string:
      return "string " + quote_text(v.get_ref<const std::string&>(), '"');
    case json::value_t::array:
      return "an array";
    case json::value_t::object:
      return "an object";
    default:
      return "an unsupported value";
  }
}

std::string join_key(std::string_view path, std::string_view key) {
  std::string out(path);
  if (!out.empty()) out += '.';
  out += key;
  return out;
}

std::string join_index(std::string_view path, std::size_t index) {
  std::string out(path);
  out += '[';
  append_int(out, index);
  out += ']';
  return out;
}

int line_of_path(std::string_view text, std::string path) {
  for (;;) {
    const int line = find_line(text, path);
    if (line > 0) return line;
    if (path.empty()) return 1;
    // Strip the last component: "a.b[2]" -> "a.b" -> "a" -> "".
    const std::size_t cut = path.find_last_of(".[");
    path.resize(cut == std::string::npos ? 0 : cut);
  }
}

namespace {

/// SAX handler building a json DOM, tracking field paths, refusing duplicate keys.
class DomBuilder {
 public:
  using number_integer_t = json::number_integer_t;
  using number_unsigned_t = json::number_unsigned_t;
  using number_float_t = json::number_float_t;
  using string_t = json::string_t;
  using binary_t = json::binary_t;

  /// `text` is the whole input; with `want_lines`, a duplicate key's message
  /// names the line of its first occurrence.
  DomBuilder(json* root, const LineCounter* counter, std::string_view text, bool want_lines)
      : root_(root), counter_(counter), text_(text), want_lines_(want_lines) {}

  bool null() { return place(json(nullptr)) != nullptr; }
  bool boolean(bool v) { return place(json(v)) != nullptr; }
  bool number_integer(number_integer_t v) { return place(json(v)) != nullptr; }
  bool number_unsigned(number_unsigned_t v) { return place(json(v)) != nullptr; }
  bool number_float(number_float_t v, const string_t& /*text*/) {
    // The parser refuses non-finite results (error 406) before calling us.
    return place(json(v)) != nullptr;
  }
  bool string(string_t& v) { return place(json(std::move(v))) != nullptr; }
  bool binary(binary_t& /*v*/) { return fail(path_, "binary values are not JSON"); }

  bool start_object(std::size_t /*elements*/) {
    json* slot = place(json(json::value_t::object));
    return slot != nullptr && push(slot);
  }
  bool key(string_t& k) {
    Level& top = stack_.back();
    path_.resize(top.path_len);
    if (!path_.empty()) path_ += '.';
    path_ += k;
    if (top.value->contains(k)) {
      const int first = want_lines_ ? find_line(text_, path_) : 0;
      std::string msg = "duplicate key " + quote_text(k);
      if (first > 0) msg += ", first at line " + std::to_string(first);
      path_.resize(top.path_len);
      return fail(path_, msg);
    }
    pending_key_ = std::move(k);
    return true;
  }
  bool end_object() {
    stack_.pop_back();
    return true;
  }
  bool start_array(std::size_t /*elements*/) {
    json* slot = place(json(json::value_t::array));
    return slot != nullptr && push(slot);
  }
  bool end_array() {
    stack_.pop_back();
    return true;
  }

  bool parse_error(std::size_t /*position*/, const std::string& last_token,
                   const json::exception& ex) {
    failed_ = true;
    error_line_ = counter_->token_line;
    if (ex.id == 406) {
      // Number overflow: the only way to write an infinity in JSON.
      error_field_ = pending_field();
      error_message_ = "number " + quote_text(last_token) +
                       " is out of range: numbers must be finite (and at most " +
                       number_text(kMaxCoordinate) + " in magnitude for coordinates)";
      return false;
    }
    std::string what = ex.what();
    // "[json.exception.parse_error.101] parse error at line 1, column 9: syntax error ..."
    const std::size_t col = what.find("column ");
    std::size_t start = std::string::npos;
    if (col != std::string::npos) start = what.find(": ", col);
    if (start == std::string::npos) start = what.find("] ");
    if (start != std::string::npos) what.erase(0, start + 2);
    error_message_ = "malformed JSON (column " + std::to_string(counter_->token_column) + "): " + what;
    return false;
  }

  bool failed() const { return failed_; }
  int error_line() const { return error_line_; }
  const std::string& error_field() const { return error_field_; }
  const std::string& error_message() const { return error_message_; }

 private:
  struct Level {
    json* value;
    std::size_t path_len;  ///< Length of this container's path in path_.
    std::size_t index;     ///< Next element index (arrays).
  };

  bool fail(const std::string& field, std::string message) {
    failed_ = true;
    error_line_ = counter_->token_line;
    error_field_ = field;
    error_message_ = std::move(message);
    return false;
  }


  /// Path of the value the parser is about to deliver.
  std::string pending_field() const {
    if (stack_.empty()) return {};
    const Level& top = stack_.back();
    if (top.value->is_array()) return join_index(path_.substr(0, top.path_len), top.index);
    return path_;
  }

  /// Stores a new value where the parser is; returns its address.
  json* place(json&& v) {
    if (stack_.empty()) {
      *root_ = std::move(v);
      path_.clear();
      return root_;
    }
    Level& top = stack_.back();
    if (top.value->is_array()) {
      path_.resize(top.path_len);
      path_ += '[';
      append_int(path_, top.index);
      path_ += ']';
      ++top.index;
      top.value->push_back(std::move(v));
      return &top.value->back();
    }
    json& slot = (*top.value)[pending_key_];
    slot = std::move(v);
    return &slot;
  }

  bool push(json* container) {
    if (stack_.size() >= kMaxDepth) {
      return fail("", "nesting deeper than " + std::to_string(kMaxDepth) + " levels");
    }
    stack_.push_back(Level{container, path_.size(), 0});
    return true;
  }

  json* root_;
  const LineCounter* counter_;
  std::string_view text_;
  bool want_lines_;
  std::vector<Level> stack_;
  std::string path_;
  std::string pending_key_;
  bool failed_ = false;
  int error_line_ = 0;
  std::string error_field_;
  std::string error_message_;
};

}  // namespace

bool parse_dom(std::string_view text, json* root, bool want_lines, int* error_line,
               std::string* error_field, std::string* error_message) {
  LineCounter counter;
  DomBuilder builder(root, &counter, text, want_lines);
  const CountingIterator first(text.data(), &counter);
  const CountingIterator last(text.data() + text.size(), &counter);
  const bool ok = json::sax_parse(first, last, &builder, json::input_format_t::json,
                                  /*strict=*/true, /*ignore_comments=*/false);
  if (ok && !builder.failed()) return true;
  if (builder.failed()) {
    // The document has not been validated yet: the path may hold any key,
    // and the JSON library's message quotes the input's bytes as they are.
    *error_line = builder.error_line();
    *error_field = printable(builder.error_field());
    *error_message = printable(builder.error_message());
  } else {
    *error_line = counter.token_line;
    error_field->clear();
    *error_message = "malformed JSON";
  }
  return false;
}

}  // namespace voxvis::detail
