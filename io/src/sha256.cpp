#include "octshape/io/sha256.h"

#include <openssl/evp.h>
#include <openssl/hmac.h>
#include <openssl/rand.h>

#include <cstdio>
#include <vector>

#include "octshape/error.h"

namespace octshape::io {
namespace {

std::string to_hex(const std::uint8_t* bytes, std::size_t n) {
    static constexpr char kHex[] = "0123456789abcdef";
    std::string s;
    s.reserve(2 * n);
    for (std::size_t i = 0; i < n; ++i) {
        s += kHex[bytes[i] >> 4];
        s += kHex[bytes[i] & 15];
    }
    return s;
}

// libcrypto failing to hash is an environment fault (no memory, broken provider) or a Sha256
// used after finish(), never a property of the input: internal (exit 70).
[[noreturn]] void crypto_failure(const char* what) {
    throw InternalError(std::string("OpenSSL SHA-256 failed in ") + what);
}

}  // namespace

struct Sha256::Impl {
    EVP_MD_CTX* ctx = nullptr;
    ~Impl() { EVP_MD_CTX_free(ctx); }
};

Sha256::Sha256() : impl_(std::make_unique<Impl>()) {
    impl_->ctx = EVP_MD_CTX_new();
    if (impl_->ctx == nullptr) crypto_failure("EVP_MD_CTX_new");
    if (EVP_DigestInit_ex(impl_->ctx, EVP_sha256(), nullptr) != 1) {
        crypto_failure("EVP_DigestInit_ex");
    }
}

Sha256::~Sha256() = default;
Sha256::Sha256(Sha256&&) noexcept = default;
Sha256& Sha256::operator=(Sha256&&) noexcept = default;

void Sha256::update(const void* data, std::size_t n) {
    if (n == 0) return;
    if (EVP_DigestUpdate(impl_->ctx, data, n) != 1) crypto_failure("EVP_DigestUpdate");
}

std::array<std::uint8_t, 32> Sha256::finish() {
    std::array<std::uint8_t, 32> out{};
    unsigned int len = 0;
    if (EVP_DigestFinal_ex(impl_->ctx, out.data(), &len) != 1 || len != out.size()) {
        crypto_failure("EVP_DigestFinal_ex");
    }
    return out;
}

std::string Sha256::hex() {
    const auto digest = finish();
    return to_hex(digest.data(), digest.size());
}

std::string sha256_hex(std::string_view bytes) {
    Sha256 h;
    h.update(bytes.data(), bytes.size());
    return h.hex();
}

std::string sha256_file(const std::string& path) {
    std::FILE* f = std::fopen(path.c_str(), "rb");
    if (f == nullptr) throw InputError::unreadable(path, "cannot open");
    Sha256 h;
    std::vector<unsigned char> chunk(std::size_t{1} << 20);
    std::size_t got = 0;
    while ((got = std::fread(chunk.data(), 1, chunk.size(), f)) > 0) h.update(chunk.data(), got);
    const bool failed = std::ferror(f) != 0;
    std::fclose(f);
    if (failed) throw InputError::unreadable(path, "read error");
    return h.hex();
}

std::string hmac_sha256_hex(std::string_view key, std::string_view message) {
    std::array<std::uint8_t, EVP_MAX_MD_SIZE> out{};
    unsigned int len = 0;
    // A zero-length key is legal in HMAC; OpenSSL wants a non-null pointer for it.
    static const unsigned char kEmpty = 0;
    const void* key_ptr = key.empty() ? static_cast<const void*>(&kEmpty) : key.data();
    const unsigned char* msg_ptr =
        message.empty() ? &kEmpty : reinterpret_cast<const unsigned char*>(message.data());
    if (HMAC(EVP_sha256(), key_ptr, static_cast<int>(key.size()), msg_ptr, message.size(),
             out.data(), &len) == nullptr ||
        len != 32) {
        crypto_failure("HMAC");
    }
    return to_hex(out.data(), len);
}

std::string random_hex(std::size_t bytes) {
    std::vector<unsigned char> b(bytes);
    if (bytes > 0 && RAND_bytes(b.data(), static_cast<int>(bytes)) != 1) {
        crypto_failure("RAND_bytes");
    }
    return to_hex(b.data(), b.size());
}

}  // namespace octshape::io
