#pragma once
// Shared by the mesh commands (denoise, metrics, features): reading a mesh with libmesh's
// std::invalid_argument mapped to the user-facing error types.

#include <filesystem>
#include <stdexcept>
#include <string>

#include "octshape/io/error.h"
#include "octshape/io/mesh_io.h"
#include "octshape/mesh/mesh.h"

namespace octshape::app {

// Reads and validates a mesh; an invalid mesh is an InputError naming the file.
inline io::MeshData read_valid_mesh(const std::filesystem::path& path) {
    io::MeshData mesh = io::read_mesh(path);
    try {
        mesh::validate_mesh(mesh.V, mesh.F);
    } catch (const std::invalid_argument& e) {
        throw InputError::corrupt(path.string(), e.what());
    }
    return mesh;
}

// Runs `validate` and turns libmesh's std::invalid_argument into a UsageError.
template <class Params>
void validate_options(const Params& params) {
    try {
        params.validate();
    } catch (const std::invalid_argument& e) {
        throw UsageError(e.what());
    }
}

}  // namespace octshape::app
