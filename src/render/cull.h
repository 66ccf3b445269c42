#pragma once
// When back faces of a mesh can be skipped without changing the image.
#include "arthrosim/core/types.h"
#include "arthrosim/render/scene.h"

namespace arthrosim::render {

/// True if `mesh` is closed and outward (SceneMesh::closed), no triangle comes within `reach`
/// mm of `eye` (so the near plane cannot cut it open) and `eye` is outside it (even crossing
/// count of a ray; an ambiguous edge or vertex hit answers false). Back faces are then hidden
/// behind front faces along every view ray. Conservative: false whenever unsure.
bool BackFacesHidden(const SceneMesh& mesh, const Vec3& eye, double reach);

/// The box of a mesh's vertices, mm.
Eigen::AlignedBox3d MeshBox(const SceneMesh& mesh);

/// Whether the renderer may skip the back faces of `mesh` (whose vertices' box is `box`) seen
/// from `eye`: `mesh` closed and either its box farther than `reach` from the eye or
/// BackFacesHidden. A part of a closed surface (SceneMesh::whole) is decided on that surface:
/// call it with the whole and the whole's box.
bool CullBackFaces(const SceneMesh& mesh, const Eigen::AlignedBox3d& box, const Vec3& eye,
                   double reach);

}  // namespace arthrosim::render
