#include "octshape/io/csv.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>

#include "octshape/error.h"

namespace octshape::io {

std::string csv_number(double v) {
    if (!std::isfinite(v)) return "NA";
    std::ostringstream s;
    s.precision(10);
    s << v;
    return s.str();
}

std::string csv_field(const std::string& s) {
    if (s.find_first_of(",\"\n\r") == std::string::npos) return s;
    std::string out = "\"";
    for (const char ch : s) {
        if (ch == '"') out += '"';
        out += ch;
    }
    return out + "\"";
}

std::string csv_line(const std::vector<std::string>& fields) {
    std::string s;
    for (std::size_t i = 0; i < fields.size(); ++i) {
        if (i > 0) s += ',';
        s += csv_field(fields[i]);
    }
    return s + '\n';
}

int CsvTable::column(const std::string& name) const {
    const auto it = std::find(header.begin(), header.end(), name);
    return it == header.end() ? -1 : static_cast<int>(it - header.begin());
}

CsvTable read_csv(std::istream& in, const std::string& name) {
    CsvTable t;
    std::vector<std::string> record;
    std::string field;
    bool in_quotes = false;
    bool was_quoted = false;
    std::size_t line = 1;
    std::size_t record_line = 1;
    auto end_field = [&] {
        record.push_back(std::move(field));
        field.clear();
        was_quoted = false;
    };
    auto end_record = [&] {
        end_field();
        if (t.header.empty()) {
            t.header = std::move(record);
        } else if (record.size() == 1 && record[0].empty()) {
            // a blank line: ignored
        } else {
            if (record.size() != t.header.size()) {
                throw InputError::corrupt(name, "line " + std::to_string(record_line) + " has " +
                                                    std::to_string(record.size()) +
                                                    " fields, the header " +
                                                    std::to_string(t.header.size()));
            }
            t.rows.push_back(std::move(record));
        }
        record.clear();
        record_line = line;
    };
    char c = 0;
    bool any = false;
    while (in.get(c)) {
        any = true;
        if (in_quotes) {
            if (c == '"') {
                if (in.peek() == '"') {
                    in.get(c);
                    field += '"';
                } else {
                    in_quotes = false;
                }
            } else {
                if (c == '\n') ++line;
                field += c;
            }
            continue;
        }
        if (c == '"' && field.empty() && !was_quoted) {
            in_quotes = true;
            was_quoted = true;
        } else if (c == ',') {
            end_field();
        } else if (c == '\n') {
            ++line;
            end_record();
        } else if (c == '\r' && in.peek() == '\n') {
            // CRLF: the '\n' ends the record
        } else {
            field += c;
        }
    }
    if (in.bad()) throw InputError::unreadable(name, "read error");
    if (in_quotes) {
        throw InputError::corrupt(
            name, "unterminated quoted field from line " + std::to_string(record_line));
    }
    if (any && !(record.empty() && field.empty())) end_record();
    if (t.header.empty() || (t.header.size() == 1 && t.header[0].empty())) {
        throw InputError::corrupt(name, "no header line");
    }
    std::set<std::string> seen;
    for (const auto& h : t.header) {
        if (h.empty()) throw InputError::corrupt(name, "empty column name in the header");
        if (!seen.insert(h).second) {
            throw InputError::corrupt(name, "duplicate column '" + h + "'");
        }
    }
    return t;
}

CsvTable read_csv_file(const std::string& path) {
    std::error_code ec;
    const auto st = std::filesystem::status(path, ec);
    if (!std::filesystem::exists(st)) throw InputError::missing(path);
    if (!std::filesystem::is_regular_file(st)) throw InputError::not_regular(path);
    std::ifstream in(path, std::ios::binary);
    if (!in) throw InputError::unreadable(path, "cannot open");
    return read_csv(in, path);
}

}  // namespace octshape::io
