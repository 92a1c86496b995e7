// VTK's error reports become typed octshape errors (io/vtk_errors.h) with VTK's message on one
// line, and nothing on stderr.

#include "octshape/io/vtk_errors.h"

#include <vtkCommand.h>
#include <vtkExecutive.h>
#include <vtkFlyingEdges3D.h>
#include <vtkImageData.h>
#include <vtkNew.h>
#include <vtkPolyData.h>

#include <gtest/gtest.h>

#include <string>

#include "octshape/error.h"

namespace octshape::io {
namespace {

// The level-set mesh's filter (libretina/onh/src/levelset_mesh.cpp) handed a grid without
// values: VTK fails the request and, unobserved, would print and leave an empty surface.
TEST(VtkErrors, FilterFailureBecomesTheTypedErrorWithVtksMessage) {
    vtkNew<vtkImageData> img;
    img->SetDimensions(4, 4, 4);  // no scalars
    vtkNew<vtkFlyingEdges3D> fe;
    fe->SetInputData(img);
    testing::internal::CaptureStderr();
    try {
        run_vtk(fe, [&] { fe->Update(); },
                [](const std::string& m) { return AnalysisError("marching cubes (VTK): " + m); });
        ADD_FAILURE() << "no error";
    } catch (const AnalysisError& e) {
        const std::string what = e.what();
        EXPECT_NE(what.find("marching cubes (VTK): "), std::string::npos) << what;
        EXPECT_NE(what.find("vtkFlyingEdges3D"), std::string::npos) << what;
        EXPECT_EQ(what.find('\n'), std::string::npos) << what;   // one line
        EXPECT_EQ(what.find("(0x"), std::string::npos) << what;  // no addresses
        EXPECT_EQ(what.find(".cxx"), std::string::npos) << what;  // no VTK source file
    }
    EXPECT_EQ(testing::internal::GetCapturedStderr(), "");
    // The observers are gone afterwards.
    EXPECT_FALSE(fe->HasObserver(vtkCommand::ErrorEvent));
    EXPECT_FALSE(fe->GetExecutive()->HasObserver(vtkCommand::ErrorEvent));
}

// A pipeline error (reported by the executive, not the filter) is caught too.
TEST(VtkErrors, PipelineErrorOfTheExecutiveIsCaught) {
    vtkNew<vtkFlyingEdges3D> fe;  // no input connection
    testing::internal::CaptureStderr();
    const std::string m = vtk_first_error(fe, [&] { fe->Update(); });
    EXPECT_EQ(testing::internal::GetCapturedStderr(), "");
    EXPECT_NE(m.find("has 0 connections"), std::string::npos) << m;
}

TEST(VtkErrors, NoErrorNoMessageAndRunsExceptionsPassThrough) {
    vtkNew<vtkImageData> img;
    img->SetDimensions(2, 2, 2);
    img->AllocateScalars(VTK_FLOAT, 1);
    auto* v = static_cast<float*>(img->GetScalarPointer());
    for (int i = 0; i < 8; ++i) v[i] = i < 4 ? -1.0F : 1.0F;
    vtkNew<vtkFlyingEdges3D> fe;
    fe->SetInputData(img);
    fe->SetValue(0, 0.0);
    EXPECT_EQ(vtk_first_error(fe, [&] { fe->Update(); }), "");
    EXPECT_GT(fe->GetOutput()->GetNumberOfCells(), 0);
    EXPECT_THROW((void)vtk_first_error(fe, [] { throw DataError("x"); }), DataError);
    EXPECT_FALSE(fe->HasObserver(vtkCommand::ErrorEvent));
}

}  // namespace
}  // namespace octshape::io
