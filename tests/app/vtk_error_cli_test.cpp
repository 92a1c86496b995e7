// A VTK error reaches the user as octshape's one-line error with its exit code (io/vtk_errors.h):
// not VTK's multi-line printout on stderr beside it, and no output file.

#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <string>

#include "test_paths.h"

namespace octshape {
namespace {

namespace fs = std::filesystem;

TEST(VtkErrorCli, ReaderErrorIsOneLineExit65AndNoOutput) {
    test::TempDir tmp;
    const fs::path in = tmp / "cut.vtp";
    const fs::path out = tmp / "out.vtp";
    // An XML file cut after its root element: VTK's XML parser (an object inside the reader)
    // reports it, which used to be printed by VTK's logger on stderr besides our message.
    std::ofstream(in) << "<?xml version=\"1.0\"?>\n<VTKFile type=\"PolyData\">\n";
    const auto r = test::run_octshape("features '" + in.string() + "' -o '" + out.string() + "'");
    EXPECT_EQ(r.exit_code, 65) << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    EXPECT_TRUE(r.err.starts_with("octshape: error: " + in.string() +
                                  ": corrupt: VTK reader: vtkXMLDataParser: "))
        << r.err;
    EXPECT_EQ(r.err.find("0x"), std::string::npos) << r.err;
    EXPECT_FALSE(fs::exists(out));
}

}  // namespace
}  // namespace octshape
