#include "json.hpp"

#include <charconv>
#include <cmath>
#include <cstdio>

namespace dynbvh::study {

std::string json_quote(std::string_view s) {
    std::string o = "\"";
    for (char ch : s) {
        const auto c = static_cast<unsigned char>(ch);
        switch (c) {
            case '"': o += "\\\""; break;
            case '\\': o += "\\\\"; break;
            case '\n': o += "\\n"; break;
            case '\r': o += "\\r"; break;
            case '\t': o += "\\t"; break;
            default:
                if (c < 0x20) {
                    char buf[8];
                    std::snprintf(buf, sizeof buf, "\\u%04x", c);
                    o += buf;
                } else {
                    o += ch;
                }
        }
    }
    return o + "\"";
}

std::string json_number(double x) {
    if (!std::isfinite(x)) return "null";
    char buf[64];
    const auto r = std::to_chars(buf, buf + sizeof buf, x);
    return std::string(buf, r.ptr);
}

void JsonWriter::newline() {
    if (!pretty_) return;
    out_ += '\n';
    out_.append(2 * stack_.size(), ' ');
}

void JsonWriter::before_value() {
    if (after_key_) {
        after_key_ = false;
        return;
    }
    if (stack_.empty()) return;
    Level& l = stack_.back();
    if (!l.first) out_ += l.compact ? ", " : ",";
    if (!l.compact) newline();
    l.first = false;
}

void JsonWriter::open(char c, bool compact) {
    const bool parent_compact = !stack_.empty() && stack_.back().compact;
    before_value();
    out_ += c;
    stack_.push_back({true, compact || parent_compact});
}

void JsonWriter::close(char c) {
    const Level l = stack_.back();
    stack_.pop_back();
    if (!l.first && !l.compact) newline();
    out_ += c;
    if (stack_.empty() && pretty_) out_ += '\n';
}

void JsonWriter::key(std::string_view k) {
    before_value();
    out_ += json_quote(k);
    out_ += stack_.back().compact || !pretty_ ? ":" : ": ";
    after_key_ = true;
}

void JsonWriter::value(std::string_view s) {
    before_value();
    out_ += json_quote(s);
}
void JsonWriter::value(double x) {
    before_value();
    out_ += json_number(x);
}
void JsonWriter::value(bool b) {
    before_value();
    out_ += b ? "true" : "false";
}
void JsonWriter::integer(const std::string& s) {
    before_value();
    out_ += s;
}
void JsonWriter::null() {
    before_value();
    out_ += "null";
}
void JsonWriter::array3(double a, double b, double c) {
    begin_array(true);
    value(a);
    value(b);
    value(c);
    end_array();
}

} // namespace dynbvh::study
