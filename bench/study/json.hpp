// A small streaming JSON writer (no JSON library is available): objects, arrays, strings with
// escapes, numbers in shortest round-trip form, null for NaN/inf. Pretty-printed, with containers
// that can be asked to stay on one line (per-frame records).
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace dynbvh::study {

class JsonWriter {
public:
    explicit JsonWriter(bool pretty = true) : pretty_(pretty) {}

    void begin_object(bool compact = false) { open('{', compact); }
    void end_object() { close('}'); }
    void begin_array(bool compact = false) { open('[', compact); }
    void end_array() { close(']'); }
    void key(std::string_view k);

    void value(std::string_view s);
    void value(const char* s) { value(std::string_view(s)); }
    void value(const std::string& s) { value(std::string_view(s)); }
    void value(double x);
    void value(float x) { value(double(x)); }
    void value(bool b);
    void value(int x) { integer(std::to_string(x)); }
    void value(unsigned x) { integer(std::to_string(x)); }
    void value(long x) { integer(std::to_string(x)); }
    void value(unsigned long x) { integer(std::to_string(x)); }
    void value(long long x) { integer(std::to_string(x)); }
    void value(unsigned long long x) { integer(std::to_string(x)); }
    template <class T>
    void value(const std::optional<T>& x) {
        if (x) value(*x);
        else null();
    }
    void null();
    void array3(double a, double b, double c);

    template <class T>
    void kv(std::string_view k, const T& v) {
        key(k);
        value(v);
    }

    const std::string& str() const noexcept { return out_; }

private:
    struct Level {
        bool first = true;
        bool compact = false;
    };
    void open(char c, bool compact);
    void close(char c);
    void before_value();
    void integer(const std::string& s);
    void newline();

    std::string out_;
    std::vector<Level> stack_;
    bool after_key_ = false;
    bool pretty_;
};

/// `s` as a JSON string literal (quotes included).
std::string json_quote(std::string_view s);
/// Shortest text that reads back as `x`; "null" for NaN/inf.
std::string json_number(double x);

} // namespace dynbvh::study
