#pragma once
// CSV as octshape writes and reads it (RFC 4180): fields quoted when they hold a comma, quote or
// line break; numbers with 10 significant digits; missing values "NA". Every table octshape
// writes (eyes.csv, failures.csv, per-eye rows) and reads (eyes.csv for `stats`, map files)
// goes through here.

#include <istream>
#include <string>
#include <vector>

namespace octshape::io {

// A finite number with 10 significant digits, or "NA".
[[nodiscard]] std::string csv_number(double v);
// Quotes a CSV field when it holds a comma, quote or newline (RFC 4180).
[[nodiscard]] std::string csv_field(const std::string& s);
// One CSV line (fields quoted as needed, '\n' at the end).
[[nodiscard]] std::string csv_line(const std::vector<std::string>& fields);

// A CSV table of strings (quoted fields may hold commas, quotes and newlines).
struct CsvTable {
    std::vector<std::string> header;
    std::vector<std::vector<std::string>> rows;  // every row has header.size() fields
    // Index of a column, or -1.
    [[nodiscard]] int column(const std::string& name) const;
};

// Parses a CSV table; CRLF or LF line ends, blank lines ignored. `name` is used in errors.
// Throws InputError::corrupt (with the line) on an unterminated quote, a row with the wrong
// number of fields or an empty/duplicate header.
[[nodiscard]] CsvTable read_csv(std::istream& in, const std::string& name);
// Opens and parses a file (InputError missing/not regular/unreadable when it cannot be read).
[[nodiscard]] CsvTable read_csv_file(const std::string& path);

}  // namespace octshape::io
