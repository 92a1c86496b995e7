#include "xml_dom.h"

#include <fstream>

#include <filesystem>

#include <cctype>
#include <cstdint>

#include "octshape/error.h"

namespace octshape::io::detail {
namespace {

bool is_name_char(char c) {
    const auto u = static_cast<unsigned char>(c);
    return std::isalnum(u) != 0 || c == '_' || c == '-' || c == '.' || c == ':' || u >= 0x80;
}
bool is_space(char c) { return c == ' ' || c == '\t' || c == '\n' || c == '\r'; }

void append_utf8(std::string& out, std::uint32_t cp) {
    if (cp < 0x80) {
        out += static_cast<char>(cp);
    } else if (cp < 0x800) {
        out += static_cast<char>(0xC0 | (cp >> 6));
        out += static_cast<char>(0x80 | (cp & 0x3F));
    } else if (cp < 0x10000) {
        out += static_cast<char>(0xE0 | (cp >> 12));
        out += static_cast<char>(0x80 | ((cp >> 6) & 0x3F));
        out += static_cast<char>(0x80 | (cp & 0x3F));
    } else {
        out += static_cast<char>(0xF0 | (cp >> 18));
        out += static_cast<char>(0x80 | ((cp >> 12) & 0x3F));
        out += static_cast<char>(0x80 | ((cp >> 6) & 0x3F));
        out += static_cast<char>(0x80 | (cp & 0x3F));
    }
}

class Parser {
public:
    Parser(std::string_view doc, const std::string& path) : s_(doc), path_(path) {}

    XmlNode document() {
        skip_prolog();
        if (pos_ >= s_.size() || s_[pos_] != '<') fail("no root element");
        XmlNode root = element(1);
        skip_misc();
        if (pos_ != s_.size()) fail("content after the root element");
        return root;
    }

private:
    [[noreturn]] void fail(const std::string& what) const {
        throw InputError::corrupt(path_, "XML: " + what, pos_);
    }
    bool starts_with(std::string_view t) const { return s_.substr(pos_, t.size()) == t; }
    void expect(std::string_view t) {
        if (!starts_with(t)) fail("expected '" + std::string(t) + "'");
        pos_ += t.size();
    }
    void skip_spaces() {
        while (pos_ < s_.size() && is_space(s_[pos_])) ++pos_;
    }
    void skip_until(std::string_view end, const char* what) {
        const std::size_t at = s_.find(end, pos_);
        if (at == std::string_view::npos) fail(std::string("unterminated ") + what);
        pos_ = at + end.size();
    }
    // Comments, processing instructions and white space between elements.
    void skip_misc() {
        for (;;) {
            skip_spaces();
            if (starts_with("<!--")) {
                skip_until("-->", "comment");
            } else if (starts_with("<?")) {
                skip_until("?>", "processing instruction");
            } else {
                return;
            }
        }
    }
    void skip_prolog() {
        if (starts_with("\xEF\xBB\xBF")) pos_ += 3;  // UTF-8 byte order mark
        skip_misc();
        if (starts_with("<!DOCTYPE")) fail("DOCTYPE is not accepted (no entity definitions)");
    }
    std::string name() {
        const std::size_t start = pos_;
        while (pos_ < s_.size() && is_name_char(s_[pos_])) ++pos_;
        if (pos_ == start) fail("expected a name");
        return std::string(s_.substr(start, pos_ - start));
    }
    // Character data up to `stop`, with entities decoded.
    void char_data(std::string& out, char stop) {
        while (pos_ < s_.size() && s_[pos_] != stop) {
            if (s_[pos_] == '&') {
                entity(out);
            } else {
                if (stop == '<' || s_[pos_] != '<') {
                    out += s_[pos_];
                } else {
                    fail("'<' in attribute value");
                }
                ++pos_;
            }
        }
    }
    void entity(std::string& out) {
        const std::size_t semi = s_.find(';', pos_);
        if (semi == std::string_view::npos || semi - pos_ > 12) fail("bad entity reference");
        const std::string_view ent = s_.substr(pos_ + 1, semi - pos_ - 1);
        if (ent == "lt") {
            out += '<';
        } else if (ent == "gt") {
            out += '>';
        } else if (ent == "amp") {
            out += '&';
        } else if (ent == "quot") {
            out += '"';
        } else if (ent == "apos") {
            out += '\'';
        } else if (ent.size() >= 2 && ent[0] == '#') {
            std::uint32_t cp = 0;
            const bool hex = ent[1] == 'x' || ent[1] == 'X';
            const std::string_view digits = ent.substr(hex ? 2 : 1);
            if (digits.empty()) fail("bad character reference");
            for (char c : digits) {
                const int d = std::isdigit(static_cast<unsigned char>(c)) != 0 ? c - '0'
                              : hex && std::isxdigit(static_cast<unsigned char>(c)) != 0
                                  ? (std::tolower(static_cast<unsigned char>(c)) - 'a' + 10)
                                  : -1;
                if (d < 0) fail("bad character reference");
                cp = cp * (hex ? 16U : 10U) + static_cast<std::uint32_t>(d);
                if (cp > 0x10FFFF) fail("character reference out of range");
            }
            append_utf8(out, cp);
        } else {
            fail("unknown entity '&" + std::string(ent) + ";'");
        }
        pos_ = semi + 1;
    }
    XmlNode element(int depth) {
        if (depth > kMaxXmlDepth) fail("elements nested too deeply");
        XmlNode node;
        node.offset = pos_;
        expect("<");
        node.name = name();
        for (;;) {
            skip_spaces();
            if (pos_ >= s_.size()) fail("unterminated start tag <" + node.name + ">");
            if (starts_with("/>")) {
                pos_ += 2;
                return node;
            }
            if (s_[pos_] == '>') {
                ++pos_;
                break;
            }
            std::string key = name();
            skip_spaces();
            expect("=");
            skip_spaces();
            if (pos_ >= s_.size() || (s_[pos_] != '"' && s_[pos_] != '\'')) {
                fail("attribute value must be quoted");
            }
            const char q = s_[pos_++];
            std::string value;
            char_data(value, q);
            expect(std::string_view(&q, 1));
            node.attributes.emplace_back(std::move(key), std::move(value));
        }
        for (;;) {
            if (pos_ >= s_.size()) fail("unterminated element <" + node.name + ">");
            if (starts_with("</")) {
                pos_ += 2;
                const std::string end = name();
                if (end != node.name) {
                    fail("end tag </" + end + "> does not match <" + node.name + ">");
                }
                skip_spaces();
                expect(">");
                return node;
            }
            if (starts_with("<!--")) {
                skip_until("-->", "comment");
            } else if (starts_with("<![CDATA[")) {
                pos_ += 9;
                const std::size_t at = s_.find("]]>", pos_);
                if (at == std::string_view::npos) fail("unterminated CDATA");
                node.text.append(s_.substr(pos_, at - pos_));
                pos_ = at + 3;
            } else if (starts_with("<?")) {
                skip_until("?>", "processing instruction");
            } else if (starts_with("<!")) {
                fail("markup declaration inside an element");
            } else if (s_[pos_] == '<') {
                node.children.push_back(element(depth + 1));
            } else {
                char_data(node.text, '<');
            }
        }
    }

    std::string_view s_;
    const std::string& path_;
    std::size_t pos_ = 0;
};

}  // namespace

const XmlNode* XmlNode::child(std::string_view n) const {
    for (const XmlNode& c : children) {
        if (c.name == n) return &c;
    }
    return nullptr;
}

const XmlNode* XmlNode::find(std::string_view path) const {
    const XmlNode* node = this;
    while (node != nullptr && !path.empty()) {
        const std::size_t slash = path.find('/');
        node = node->child(path.substr(0, slash));
        path = slash == std::string_view::npos ? std::string_view{} : path.substr(slash + 1);
    }
    return node;
}

std::vector<const XmlNode*> XmlNode::children_named(std::string_view n) const {
    std::vector<const XmlNode*> out;
    for (const XmlNode& c : children) {
        if (c.name == n) out.push_back(&c);
    }
    return out;
}

const std::string* XmlNode::attribute(std::string_view n) const {
    for (const auto& [k, v] : attributes) {
        if (k == n) return &v;
    }
    return nullptr;
}

XmlNode parse_xml(std::string_view doc, const std::string& path) {
    return Parser(doc, path).document();
}

bool xml_root_is(std::string_view head, std::string_view root) {
    std::size_t pos = 0;
    while ((pos = head.find('<', pos)) != std::string_view::npos) {
        const std::string_view rest = head.substr(pos + 1);
        if (rest.starts_with("?") || rest.starts_with("!")) {
            ++pos;
            continue;
        }
        if (!rest.starts_with(root)) return false;
        // The name ends there: "<HEDX>", "<surfaces ...>", not "<surfacesX>".
        if (rest.size() == root.size()) return true;
        const char c = rest[root.size()];
        return c == '>' || c == '/' || c == ' ' || c == '\t' || c == '\r' || c == '\n';
    }
    return false;
}

std::string read_whole_file(const std::string& path, std::uintmax_t max_bytes,
                            const std::string& what) {
    std::error_code ec;
    const std::uintmax_t size = std::filesystem::file_size(path, ec);
    if (ec) throw InputError::unreadable(path, ec.message());
    if (size > max_bytes) {
        throw InputError::unsupported(path, what + " larger than " +
                                                std::to_string(max_bytes >> 20U) + " MiB");
    }
    std::ifstream in(path, std::ios::binary);
    if (!in) throw InputError::unreadable(path, "cannot open");
    std::string doc(static_cast<std::size_t>(size), '\0');
    in.read(doc.data(), static_cast<std::streamsize>(size));
    if (static_cast<std::uintmax_t>(in.gcount()) != size) {
        throw InputError::unreadable(path, "short read");
    }
    return doc;
}

}  // namespace octshape::io::detail
