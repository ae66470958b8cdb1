"""The FEM problem of the ccx harness (ccx_reference.py): materials, load cases and the mesh, as
read from a springfit scene by ccx_scene.py and written as decks by ccx_deck.py; SceneError
when a scene cannot be turned into a CalculiX model. Python 3 standard library only.
"""


class SceneError(Exception):
    """The scene cannot be turned into a CalculiX model."""


class Material:
    def __init__(self, model, young, poisson):
        self.model = model
        self.young = float(young)
        self.poisson = float(poisson)

    def lame(self):
        e, nu = self.young, self.poisson
        lam = e * nu / ((1.0 + nu) * (1.0 - 2.0 * nu))
        mu = e / (2.0 * (1.0 + nu))
        return lam, mu


class LoadCase:
    """constraints: {node: {dof: value}} (dof 0-based); forces: {node: [f0, f1(, f2)]}."""

    def __init__(self, name="", constraints=None, forces=None):
        self.name = name
        self.constraints = constraints if constraints is not None else {}
        self.forces = forces if forces is not None else {}


class Problem:
    """A linear-triangle (2D) or linear-tetrahedron (3D) FEM problem, 0-based node indices.

    plane: "stress" or "strain" (2D only). element_materials[e] indexes materials.
    """

    def __init__(self, nodes, elements, materials, element_materials, cases,
                 plane="stress", thickness=1.0, name=""):
        self.nodes = [[float(c) for c in p] for p in nodes]
        self.dim = len(self.nodes[0])
        self.elements = [list(e) for e in elements]
        self.materials = materials
        self.element_materials = list(element_materials)
        self.cases = cases
        self.plane = plane
        self.thickness = float(thickness)
        self.name = name

    def nonlinear(self):
        models = {self.materials[m].model for m in set(self.element_materials)}
        if "neo_hookean" in models:
            raise SceneError("material model neo_hookean is not compared with ccx "
                             "(only linear and st_venant_kirchhoff)")
        if len(models) > 1:
            raise SceneError("materials mix linear and st_venant_kirchhoff: ccx runs one "
                             "analysis type (NLGEOM or not) for the whole model")
        return models == {"st_venant_kirchhoff"}
