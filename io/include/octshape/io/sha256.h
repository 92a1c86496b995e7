#pragma once
// SHA-256 (FIPS 180-4) of inputs, recorded in every output so a number can be traced to the
// exact bytes it came from. Self-contained: no crypto library is needed for a checksum.

#include <array>
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>

namespace octshape::io {

class Sha256 {
public:
    Sha256();
    void update(const void* data, std::size_t n);
    // Finishes and returns the digest; the object must not be updated afterwards.
    std::array<std::uint8_t, 32> finish();
    // Finishes and returns the lowercase hex digest.
    std::string hex();

private:
    void block(const std::uint8_t* p);
    std::array<std::uint32_t, 8> h_{};
    std::array<std::uint8_t, 64> buf_{};
    std::size_t buf_len_ = 0;
    std::uint64_t total_ = 0;
};

[[nodiscard]] std::string sha256_hex(std::string_view bytes);
// Hash of a whole file, read in chunks. Throws InputError if it cannot be read.
[[nodiscard]] std::string sha256_file(const std::string& path);

}  // namespace octshape::io
