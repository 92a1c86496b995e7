#include "octshape/io/sha256.h"

#include <fstream>
#include <string>

#include <gtest/gtest.h>

#include "octshape/io/error.h"
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

}  // namespace
}  // namespace octshape::io
