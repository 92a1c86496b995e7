#include "octshape/io/atomic_file.h"

#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>

#include <gtest/gtest.h>

#include "octshape/error.h"
#include "test_paths.h"

namespace octshape::io {
namespace {

namespace fs = std::filesystem;

std::string read_all(const fs::path& p) {
    std::ifstream in(p, std::ios::binary);
    std::ostringstream ss;
    ss << in.rdbuf();
    return ss.str();
}

TEST(AtomicFile, WritesAndReplaces) {
    test::TempDir dir;
    const auto p = dir / "out.json";
    write_text_atomically(p.string(), "first");
    EXPECT_EQ(read_all(p), "first");
    write_text_atomically(p.string(), "second");
    EXPECT_EQ(read_all(p), "second");
    // Nothing but the result is left in the directory.
    EXPECT_EQ(std::distance(fs::directory_iterator(dir.path()), fs::directory_iterator{}), 1);
}

TEST(AtomicFile, ThrowingWriterLeavesOldContentAndNoTemporary) {
    test::TempDir dir;
    const auto p = dir / "out.csv";
    write_text_atomically(p.string(), "old");
    EXPECT_THROW(write_file_atomically(p.string(),
                                       [](std::ostream& out) {
                                           out << "partial";
                                           throw std::runtime_error("analysis failed midway");
                                       }),
                 std::runtime_error);
    EXPECT_EQ(read_all(p), "old");
    EXPECT_EQ(std::distance(fs::directory_iterator(dir.path()), fs::directory_iterator{}), 1);
}

TEST(AtomicFile, NonDurableWriteIsStillAtomic) {
    // Without fsync the same temporary + rename protocol applies: the result, nothing else,
    // and a throwing writer leaves the old content.
    test::TempDir dir;
    const auto p = dir / "eye.json";
    const AtomicWriteOptions fast{.durable = false};
    write_text_atomically(p.string(), "first", fast);
    write_text_atomically(p.string(), "second", fast);
    EXPECT_EQ(read_all(p), "second");
    EXPECT_THROW(write_file_atomically(
                     p.string(),
                     [](std::ostream& out) {
                         out << "partial";
                         throw std::runtime_error("killed midway");
                     },
                     fast),
                 std::runtime_error);
    EXPECT_EQ(read_all(p), "second");
    EXPECT_EQ(std::distance(fs::directory_iterator(dir.path()), fs::directory_iterator{}), 1);
}

TEST(AtomicFile, MissingDirectoryIsAnOutputError) {
    test::TempDir dir;
    try {
        write_text_atomically((dir / "no" / "such" / "f.txt").string(), "x");
        FAIL() << "expected OutputError";
    } catch (const OutputError& e) {
        EXPECT_EQ(e.exit_code(), ExitCode::kCantCreate);
        EXPECT_NE(std::string(e.what()).find("f.txt"), std::string::npos);
    }
}

TEST(AtomicFile, DirectoryAsDestinationIsAnOutputError) {
    test::TempDir dir;
    EXPECT_THROW(write_text_atomically(dir.path().string(), "x"), OutputError);
}

}  // namespace
}  // namespace octshape::io
