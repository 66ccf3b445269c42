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

/// Whether the renderer may skip the back faces of `mesh` seen from `eye`: decided on the mesh,
/// or for a part of a closed surface (SceneMesh::whole) on that surface: no triangle within
/// `reach` mm and the eye outside (BackFacesHidden), with a box test first (a mesh whose box is
/// farther than `reach` from the eye needs no exact test).
bool CullBackFaces(const SceneMesh& mesh, const Vec3& eye, double reach);

}  // namespace arthrosim::render
