#pragma once
// Mesh files a URDF names for collision geometry: where they are, and their vertices. Used by
// `poise robot init` (sole rectangles of mesh feet) and the simulator (a non-foot link's mesh
// collides as its convex hull).

#include <Eigen/Core>
#include <filesystem>
#include <string>
#include <vector>

namespace poise::model {

/// A URDF mesh filename: "package://PKG/REST" is looked for as REST and PKG/REST in the URDF's
/// folder and its parents (no ROS package index here), "file://PATH" and plain paths as given
/// (relative: from the URDF's folder). Empty when not found.
std::filesystem::path resolve_mesh_path(const std::string& name,
                                        const std::filesystem::path& urdf_dir);

/// Vertices of an STL (binary or ASCII), OBJ or COLLADA (.dae) mesh file, at most 64 MB, in the
/// file's units except COLLADA's, which are metres by its <unit meter> (the URDF's <mesh scale>
/// is the caller's). COLLADA as ROS reads it for a URDF (rviz, MoveIt): the visual scene's
/// geometries placed by their nodes' transforms, <up_axis> not applied. Throws ModelError
/// naming the file: unreadable, another format, malformed, or no vertex.
std::vector<Eigen::Vector3d> read_mesh_vertices(const std::filesystem::path& path);

/// A collision mesh as a URDF names it (`filename`, `scale`), its vertices scaled into `points`.
/// Returns "" on success, else the problem in words: a zero or non-finite scale factor, a file
/// not found (or not a regular file), a file that cannot be read (read_mesh_vertices' reason),
/// fewer than 4 vertices. The simulator, `poise model info` and `poise robot init` all use it,
/// so that a mesh one of them refuses, every one refuses.
std::string read_collision_mesh(const std::string& filename, const Eigen::Vector3d& scale,
                                const std::filesystem::path& urdf_dir,
                                std::vector<Eigen::Vector3d>& points);

/// Every collision mesh of the URDF text checked with read_collision_mesh: one line per problem,
/// "link 'L': collision mesh 'F': reason" (empty: all readable).
std::vector<std::string> collision_mesh_problems(const std::string& urdf_xml,
                                                 const std::filesystem::path& urdf_dir);

}  // namespace poise::model
