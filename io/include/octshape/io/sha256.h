#pragma once
// SHA-256 (FIPS 180-4) of inputs, recorded in every output so a number can be traced to the
// exact bytes it came from, and HMAC-SHA256 (RFC 2104) for keyed subject pseudonyms. Backed by
// OpenSSL's libcrypto, which uses the CPU's SHA extensions where present: hashing must not be
// what limits a cohort run (docs/cohort.md).

#include <array>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <string_view>

namespace octshape::io {

class Sha256 {
public:
    Sha256();
    ~Sha256();
    Sha256(const Sha256&) = delete;
    Sha256& operator=(const Sha256&) = delete;
    Sha256(Sha256&&) noexcept;
    Sha256& operator=(Sha256&&) noexcept;

    void update(const void* data, std::size_t n);
    // Finishes and returns the digest; the object must not be updated afterwards.
    std::array<std::uint8_t, 32> finish();
    // Finishes and returns the lowercase hex digest.
    std::string hex();

private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

[[nodiscard]] std::string sha256_hex(std::string_view bytes);
// Hash of a whole file, read in chunks. Throws InputError if it cannot be read.
[[nodiscard]] std::string sha256_file(const std::string& path);
// HMAC-SHA256 of `message` under `key`, lowercase hex (64 characters).
[[nodiscard]] std::string hmac_sha256_hex(std::string_view key, std::string_view message);
// `bytes` bytes from OpenSSL's CSPRNG (RAND_bytes), lowercase hex (2 * bytes characters): the
// secret keys a cohort makes for itself (subject ids, eye keys).
[[nodiscard]] std::string random_hex(std::size_t bytes);

}  // namespace octshape::io
