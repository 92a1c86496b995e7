#pragma once
// VTK reports a failure by an ErrorEvent on the object (a pipeline failure: on the algorithm's
// executive) and, when nobody observes it, prints it on stderr and goes on with an empty
// output. Every VTK filter, reader, writer and transform octshape runs goes through
// vtk_first_error / run_vtk, which turn the first report into the caller's typed error.
// Include only where VTK is used: the callers link VTK themselves.

#include <functional>
#include <string>

class vtkObject;

namespace octshape::io {

enum class VtkReport { kErrors, kErrorsAndWarnings };

// Runs `run` with `object` (and, for a vtkAlgorithm, its executive) observed. Returns the first
// error (with kErrorsAndWarnings: or warning) VTK reported, as "Class: message" on one line
// (VTK's own text also names its source file and the object's address), or "" if none.
// Exceptions from `run` pass through; the observers are removed in every case.
[[nodiscard]] std::string vtk_first_error(vtkObject* object, const std::function<void()>& run,
                                          VtkReport report = VtkReport::kErrors);

// vtk_first_error, then throws make_error(message) if VTK reported one.
template <class MakeError>
void run_vtk(vtkObject* object, const std::function<void()>& run, MakeError&& make_error,
             VtkReport report = VtkReport::kErrors) {
    const std::string message = vtk_first_error(object, run, report);
    if (!message.empty()) throw make_error(message);
}

}  // namespace octshape::io
