#pragma once
// A small, strict XML reader for the Heidelberg XML export (private to io/).
//
// Supports elements, attributes, text, comments, CDATA, processing instructions (skipped), the
// five predefined entities and numeric character references. Rejects DOCTYPE (so no entity
// expansion attacks), nesting deeper than kMaxDepth, and anything malformed, with an
// InputError naming the file and the byte offset. Memory is bounded by the input size.

#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

namespace octshape::io::detail {

struct XmlNode {
    std::string name;
    std::vector<std::pair<std::string, std::string>> attributes;
    std::string text;  // concatenated character data directly inside this element
    std::vector<XmlNode> children;
    std::size_t offset = 0;  // byte offset of the start tag

    // First child element with this name, or nullptr.
    [[nodiscard]] const XmlNode* child(std::string_view n) const;
    // Follows a path of child names ("A/B/C"); nullptr if any step is missing.
    [[nodiscard]] const XmlNode* find(std::string_view path) const;
    // All child elements with this name.
    [[nodiscard]] std::vector<const XmlNode*> children_named(std::string_view n) const;
    // Attribute value, or nullptr.
    [[nodiscard]] const std::string* attribute(std::string_view n) const;
};

inline constexpr int kMaxXmlDepth = 64;

// Parses a whole document; returns the root element. Throws InputError(path, ..., offset).
[[nodiscard]] XmlNode parse_xml(std::string_view doc, const std::string& path);

// True when `head` (a file's first bytes) is an XML document whose root element is named
// `root`: declarations, comments and processing instructions may come first.
[[nodiscard]] bool xml_root_is(std::string_view head, std::string_view root);

// The whole file at `path`, read once. Larger than `max_bytes`: InputError (unsupported,
// "`what` larger than ..."); unreadable or short: InputError naming the file.
[[nodiscard]] std::string read_whole_file(const std::string& path, std::uintmax_t max_bytes,
                                          const std::string& what);

}  // namespace octshape::io::detail
