#include "octshape/io/atomic_file.h"

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <thread>

#include <sys/stat.h>

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

TEST(AtomicFile, AJournalTakesBackWhatAFailedRunPublished) {
    test::TempDir dir;
    write_text_atomically((dir / "old.csv").string(), "old");
    try {
        OutputJournal journal;
        write_text_atomically((dir / "a.png").string(), "picture");
        write_text_atomically((dir / "old.csv").string(), "new");
        {
            OutputJournal inner;  // a nested journal hands its files to the outer one
            write_text_atomically((dir / "b.png").string(), "picture");
            inner.commit();
        }
        EXPECT_TRUE(fs::exists(dir / "b.png"));
        throw std::runtime_error("the run fails after its pictures");
    } catch (const std::runtime_error&) {
    }
    for (const char* n : {"a.png", "b.png", "old.csv"}) EXPECT_FALSE(fs::exists(dir / n)) << n;
    {
        OutputJournal journal;
        write_text_atomically((dir / "kept.json").string(), "{}");
        journal.commit();
    }
    EXPECT_EQ(read_all(dir / "kept.json"), "{}");
}

// A FIFO is written through a temporary file: with TMPDIR not a folder that is an OutputError
// (exit 73) naming the destination, not std::filesystem's exception (which was exit 70).
TEST(AtomicFile, NoTemporaryFolderIsAnOutputError) {
    test::TempDir dir;
    const fs::path fifo = dir / "f";
    ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
    std::ofstream(dir / "plain") << "x";
    const char* old = std::getenv("TMPDIR");
    const std::string saved = old != nullptr ? old : "";
    ::setenv("TMPDIR", (dir / "plain").c_str(), 1);
    try {
        write_path_atomically(fifo.string(), [](const std::string&) {});
        ADD_FAILURE() << "no error";
    } catch (const OutputError& e) {
        EXPECT_EQ(e.path(), fifo.string());
    }
    if (old != nullptr) {
        ::setenv("TMPDIR", saved.c_str(), 1);
    } else {
        ::unsetenv("TMPDIR");
    }
}

TEST(AtomicFile, ASymlinkIsWrittenThroughAndAFifoInto) {
    test::TempDir dir;
    write_text_atomically((dir / "target.txt").string(), "old");
    fs::create_symlink(dir / "target.txt", dir / "link.txt");
    write_text_atomically((dir / "link.txt").string(), "new");
    EXPECT_TRUE(fs::is_symlink(dir / "link.txt"));
    EXPECT_EQ(read_all(dir / "target.txt"), "new");
    // The path writer (VTK's formats) into a FIFO: a reader gets the bytes, the FIFO stays.
    const fs::path fifo = dir / "f";
    ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
    std::string got;
    std::thread reader([&] { got = read_all(fifo); });
    write_path_atomically(fifo.string(), [](const std::string& tmp) {
        std::ofstream(tmp) << "mesh";
    });
    reader.join();
    EXPECT_EQ(got, "mesh");
    EXPECT_TRUE(fs::is_fifo(fifo));
    EXPECT_THROW(check_output_location((dir / "nope" / "x").string()), OutputError);
    EXPECT_THROW(check_output_location(dir.path().string()), OutputError);
    EXPECT_NO_THROW(check_output_location("-"));
    EXPECT_NO_THROW(check_output_location((dir / "link.txt").string()));
    EXPECT_THROW(check_output_directory((dir / "target.txt").string()), OutputError);
    EXPECT_NO_THROW(check_output_directory((dir / "new" / "deeper").string()));
    EXPECT_FALSE(fs::exists(dir / "new"));  // checked, not created
}

}  // namespace
}  // namespace octshape::io
