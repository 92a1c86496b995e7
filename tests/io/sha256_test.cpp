#include "octshape/io/sha256.h"

#include <fstream>
#include <string>

#include <gtest/gtest.h>

#include "octshape/error.h"
#include "test_paths.h"

namespace octshape::io {
namespace {

// FIPS 180-4 / NIST example vectors.
TEST(Sha256, NistVectors) {
    EXPECT_EQ(sha256_hex(""), "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855");
    EXPECT_EQ(sha256_hex("abc"),
              "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
    EXPECT_EQ(sha256_hex("abcdbcdecdefdefgefghfghighijhijkijkljklmklmnlmnomnopnopq"),
              "248d6a61d20638b8e5c026930c3e6039a33ce45964ff2167f6ecedd419db06c1");
    EXPECT_EQ(sha256_hex(std::string(1000000, 'a')),
              "cdc76e5c9914fb9281a1c7e284d73e67f1809a48a497200e046d39ccc7112cd0");
}

TEST(Sha256, ChunkingDoesNotMatter) {
    std::string data;
    for (int i = 0; i < 1000; ++i) data += static_cast<char>(i * 7 + 3);
    const std::string whole = sha256_hex(data);
    for (std::size_t step : {1U, 3U, 63U, 64U, 65U, 500U}) {
        Sha256 h;
        for (std::size_t i = 0; i < data.size(); i += step) {
            h.update(data.data() + i, std::min(step, data.size() - i));
        }
        EXPECT_EQ(h.hex(), whole) << "step " << step;
    }
}

TEST(Sha256, FileMatchesMemory) {
    test::TempDir dir;
    const auto p = dir / "f.bin";
    std::ofstream(p, std::ios::binary) << "abc";
    EXPECT_EQ(sha256_file(p.string()), sha256_hex("abc"));
    EXPECT_THROW((void)sha256_file((dir / "missing").string()), InputError);
}

// A file longer than the 1 MiB read chunk, with a length that is not a multiple of it.
TEST(Sha256, MultiChunkFileMatchesMemory) {
    test::TempDir dir;
    const auto p = dir / "big.bin";
    std::string data((std::size_t{1} << 20) * 2 + 12345, '\0');
    for (std::size_t i = 0; i < data.size(); ++i) data[i] = static_cast<char>((i * 131) >> 3);
    std::ofstream(p, std::ios::binary) << data;
    EXPECT_EQ(sha256_file(p.string()), sha256_hex(data));
}

// RFC 4231 test cases 1, 2 and 6 (the last with a key longer than the block size).
TEST(HmacSha256, Rfc4231Vectors) {
    EXPECT_EQ(hmac_sha256_hex(std::string(20, '\x0b'), "Hi There"),
              "b0344c61d8db38535ca8afceaf0bf12b881dc200c9833da726e9376c2e32cff7");
    EXPECT_EQ(hmac_sha256_hex("Jefe", "what do ya want for nothing?"),
              "5bdcc146bf60754e6a042426089575c75a003f089d2739839dec58b964ec3843");
    EXPECT_EQ(hmac_sha256_hex(std::string(131, '\xaa'),
                              "Test Using Larger Than Block-Size Key - Hash Key First"),
              "60e431591ee0b67f0d8a26aacbf5b77f8e0bc6213728c5140546040f0ee37f54");
    EXPECT_NE(hmac_sha256_hex("", "x"), hmac_sha256_hex("k", "x"));
}

// The cohort's own keys (OUTDIR/private/eye.key, subject.key): 2n lowercase hex digits from
// the CSPRNG; two draws of 256 bits agree with probability 2^-256.
TEST(RandomHex, LowercaseHexOfTheLengthAskedAndNeverTheSame) {
    const std::string a = random_hex(32);
    const std::string b = random_hex(32);
    EXPECT_EQ(a.size(), 64U);
    EXPECT_EQ(a.find_first_not_of("0123456789abcdef"), std::string::npos) << a;
    EXPECT_NE(a, b);
    EXPECT_EQ(random_hex(0), "");
}

}  // namespace
}  // namespace octshape::io
