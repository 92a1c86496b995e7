#pragma once
// A small, strict XML reader for the Heidelberg XML export (private to io/).
//
// Supports elements, attributes, text, comments, CDATA, processing instructions (skipped), the
// five predefined entities and numeric character references. Rejects DOCTYPE (so no entity
// expansion attacks), nesting deeper than kMaxDepth, and anything malformed, with an
// InputError naming the file and the byte offset. Memory is bounded by the input size.

#include <cstddef>
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

}  // namespace octshape::io::detail
