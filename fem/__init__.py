"""fem: a small, vectorised finite-element library for 3D elasticity.

It knows nothing of hands or contact. Meshes of TET4, HEX8 and WEDGE6 cells, sparse
stiffness assembly, loads, the partitioned solve of prescribed displacements with
reactions, free bodies, stresses, generators, meshing and IO; linear elasticity, and
neo-Hookean finite strain solved by Newton's method (:mod:`fem.hyperelastic`,
:mod:`fem.newton`).
"""

from __future__ import annotations

from .assembly import assemble_stiffness, element_stiffness
from .dofs import element_dofs, node_dofs
from .eigen3 import eigh3, rotation_svd3
from .elements import ELEMENTS, HEX8, TET4, WEDGE6, ReferenceElement
from .errors import (
    FemError,
    LoadError,
    MaterialError,
    MeshError,
    NoVolumeCellsError,
    SolverError,
)
from .generators import ball_mesh, graded_ball_mesh, shell_mesh
from .graded_tets import graded_tet_octant
from .grids import box_mesh, hex_to_tet
from .hyperelastic import FiniteStrain, cauchy_stress, finite_strain, log_strain, neo_hookean
from .io import read_mesh, read_mesh_data, write_mesh
from .linsolve import available_backends, factorize
from .loads import (
    STANDARD_GRAVITY,
    gravity_load,
    initial_stress_load,
    point_load,
    pressure_load,
)
from .material import LinearElastic, elasticity_matrix, lame
from .mesh import BoundaryFaces, Mesh, bounding_box
from .meshing import check_surface, sphere_surface, tetrahedralize
from .newton import NewtonSolution, solve_finite_strain
from .nodalpressure import nodal_dilatation, nodal_pressure_correction
from .pvmesh import from_pyvista, to_pyvista
from .saddle import rigid_part, turned_placement
from .statics import StaticSolution, StaticSolver, check_balance, rigid_body_modes
from .stress import cell_stress, gauss_strain, nodal_average, von_mises
from .threads import dense_threads, sparse_threads
from .turning import TurningInverse

__version__ = "0.1.0"

__all__ = [
    "ELEMENTS",
    "HEX8",
    "STANDARD_GRAVITY",
    "TET4",
    "WEDGE6",
    "BoundaryFaces",
    "FemError",
    "FiniteStrain",
    "LinearElastic",
    "LoadError",
    "MaterialError",
    "Mesh",
    "MeshError",
    "NewtonSolution",
    "NoVolumeCellsError",
    "ReferenceElement",
    "SolverError",
    "StaticSolution",
    "StaticSolver",
    "TurningInverse",
    "__version__",
    "assemble_stiffness",
    "available_backends",
    "ball_mesh",
    "bounding_box",
    "box_mesh",
    "cauchy_stress",
    "cell_stress",
    "check_balance",
    "check_surface",
    "dense_threads",
    "eigh3",
    "elasticity_matrix",
    "element_dofs",
    "element_stiffness",
    "factorize",
    "finite_strain",
    "from_pyvista",
    "gauss_strain",
    "graded_ball_mesh",
    "graded_tet_octant",
    "gravity_load",
    "hex_to_tet",
    "initial_stress_load",
    "lame",
    "log_strain",
    "neo_hookean",
    "nodal_average",
    "nodal_dilatation",
    "nodal_pressure_correction",
    "node_dofs",
    "point_load",
    "pressure_load",
    "read_mesh",
    "read_mesh_data",
    "rigid_body_modes",
    "rigid_part",
    "rotation_svd3",
    "shell_mesh",
    "solve_finite_strain",
    "sparse_threads",
    "sphere_surface",
    "tetrahedralize",
    "to_pyvista",
    "turned_placement",
    "von_mises",
    "write_mesh",
]
