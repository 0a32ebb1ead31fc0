"""The papers' own figures, for the scripts that print them beside glvox's (``compare/table*.py``,
``compare/zhang_table1.py``).

Transcribed from the papers' tables (Schwarz & Seidel 2010, Tables 1-3,
measured on an NVIDIA GeForce GTX 285; Zhang et al. 2018, Tables 1 and 2,
the GPU column measured on an NVIDIA GeForce GTX 970 with CUDA 7.5);
``tests/test_paper_figures.py`` checks every number against the papers'
text.  Times are ms, voxel and pair counts thousands, octree sizes MB (the
paper's).  The paper's models are named as the paper names them; the shared
meshes that stand for them (:data:`SS_MODELS`) are not always the same
tessellation: the paper's Stanford dragon is the full 871,414-triangle
scan, the shared ``stanford_dragon_vrip_res2.ply`` a decimation of it.
"""

from __future__ import annotations

SS_GPU = "NVIDIA GeForce GTX 285"
ZHANG_GPU = "NVIDIA GeForce GTX 970 (CUDA 7.5)"

#: The paper's model a shared mesh stands for, and the paper's triangle count.
SS_MODELS = {
    "stanford_bunny_bun_zipper.ply": ("Stanford bunny", 69_666),
    "stanford_dragon_vrip_res2.ply": ("Stanford dragon", 871_414),
    "stanford_dragon_vrip.ply": ("Stanford dragon", 871_414),
}

_T1_COLUMNS = ("pipeline", "simple", "specialized", "sorted", "voxels_k", "cases",
               "sep6_simple", "sep6_specialized", "sep6_sorted", "sep6_voxels_k")

#: Schwarz & Seidel 2010 Table 1 (surface): model -> grid size -> {column: value}; ``pipeline`` is
#: Zhang et al. 2007's conservative voxelization (None where the paper has none), ``cases`` the
#: 1D/2D/3D percentages, ``sep6_*`` the 6-separating voxelization.
SS_TABLE1: dict[str, dict[int, dict]] = {
    model: {n: dict(zip(_T1_COLUMNS, row)) for n, row in rows.items()}
    for model, rows in {
        "Stanford bunny": {
            128: (10.39, 1.62, 1.65, 2.94, 54, (10, 49, 41), 1.60, 1.50, 2.37, 33),
            256: (10.24, 3.99, 2.51, 4.19, 222, (0, 20, 79), 3.38, 1.98, 3.16, 133),
            512: (14.80, 11.97, 5.96, 8.40, 900, (0, 9, 91), 12.40, 4.59, 6.26, 535),
            1024: (72.64, 60.96, 20.69, 26.75, 3627, (0, 3, 97), 58.08, 17.09, 18.42, 2147)},
        "Shrub": {
            128: (188.16, 27.71, 25.44, 30.39, 102, (75, 18, 7), 27.13, 15.58, 18.31, 74),
            256: (236.50, 22.57, 17.81, 23.07, 426, (57, 18, 25), 21.37, 10.88, 13.49, 274),
            512: (336.30, 36.10, 25.42, 28.94, 1705, (46, 17, 38), 34.18, 15.83, 16.61, 1022),
            1024: (804.45, 118.23, 63.49, 65.55, 6776, (22, 27, 52), 110.71, 40.95, 35.82, 3924)},
        "Stanford dragon": {
            128: (116.27, 12.67, 11.72, 16.99, 39, (89, 10, 1), 12.54, 8.91, 13.51, 25),
            256: (142.88, 9.14, 8.26, 16.84, 162, (64, 28, 8), 9.09, 6.60, 12.84, 98),
            512: (194.15, 10.93, 10.69, 20.67, 660, (24, 39, 36), 10.99, 8.15, 15.55, 387),
            1024: (331.81, 24.17, 23.00, 32.18, 2664, (8, 24, 68), 23.74, 16.24, 23.45, 1539)},
        "XYZ RGB Asian dragon": {
            128: (1261.99, 234.04, 227.37, 192.17, 22, (99, 1, 0), 230.13, 153.94, 187.02, 16),
            256: (1496.62, 111.11, 106.63, 134.08, 91, (97, 3, 0), 108.87, 76.89, 113.59, 61),
            512: (None, 73.78, 68.99, 130.76, 374, (88, 11, 1), 74.55, 54.70, 97.29, 233),
            1024: (None, 92.48, 85.26, 141.11, 1516, (60, 32, 8), 95.28, 66.59, 105.32, 897)},
    }.items()
}

_T2_COLUMNS = ("pipeline", "tri_parallel", "t_total", "t_pairs", "t_sort", "t_tiles", "pairs_k", "tris")

#: Schwarz & Seidel 2010 Table 2 (solid): ``pipeline`` is Eisemann & Decoret 2008, ``tri_parallel``
#: the triangle-parallel method, ``t_*`` the tile-based one and its break-down, ``pairs_k`` the
#: (tile, triangle) pairs and ``tris`` the average triangles per active tile.
SS_TABLE2: dict[str, dict[int, dict]] = {
    model: {n: dict(zip(_T2_COLUMNS, row)) for n, row in rows.items()}
    for model, rows in {
        "Stanford bunny": {
            128: (0.52, 0.48, 1.53, 0.38, 0.32, 0.48, 42, 64.2),
            256: (0.58, 1.48, 2.02, 0.39, 0.44, 0.80, 81, 32.2),
            512: (1.43, 9.27, 4.72, 0.49, 0.78, 2.88, 145, 14.6),
            1024: (8.75, 74.86, 18.24, 0.76, 1.39, 14.08, 301, 7.6)},
        "Stanford dragon": {
            128: (2.69, 1.45, 2.51, 1.09, 0.32, 0.47, 40, 81.8),
            256: (2.73, 2.03, 4.72, 1.21, 0.64, 1.11, 156, 84.7),
            512: (3.16, 7.57, 7.19, 1.41, 1.96, 2.91, 476, 67.3),
            1024: (13.56, 51.95, 16.41, 1.79, 3.54, 8.76, 944, 34.0)},
        "XYZ RGB Asian dragon": {
            128: (18.30, 8.84, 7.70, 5.06, 0.19, 0.44, 21, 81.5),
            256: (18.35, 8.82, 8.73, 5.48, 0.44, 0.75, 84, 89.1),
            512: (18.52, 13.77, 12.63, 6.66, 1.47, 2.18, 342, 96.3),
            1024: (20.46, 50.94, 24.26, 7.66, 4.91, 7.92, 1366, 99.6)},
    }.items()
}

#: Schwarz & Seidel 2010 Table 3 (sparse solid): row label -> model -> four values, for binary
#: grids of 512^3, 1024^3, 2048^3 and 4096^3 (:data:`SS_TABLE3_SIZES`); the labels are
#: ``compare/table3_ss_octree.py``'s rows, ``Stored level-0 nodes`` in percent, ``Octree size`` in MB.
SS_TABLE3_SIZES = (512, 1024, 2048, 4096)
SS_TABLE3: dict[str, dict[str, tuple[float, ...]]] = {
    "Total (the five stages)": {"Stanford bunny": (4.87, 9.15, 25.17, 93.27),
                                "Stanford dragon": (14.50, 23.59, 37.71, 100.32),
                                "XYZ RGB Asian dragon": (47.71, 102.96, 143.90, 178.40)},
    "Determine active level-1 nodes": {"Stanford bunny": (1.49, 1.92, 3.60, 12.74),
                                       "Stanford dragon": (8.07, 10.63, 9.02, 17.79),
                                       "XYZ RGB Asian dragon": (27.07, 80.91, 101.09, 77.79)},
    "Construct octree": {"Stanford bunny": (1.01, 1.74, 3.99, 12.36),
                         "Stanford dragon": (0.97, 1.52, 3.37, 9.43),
                         "XYZ RGB Asian dragon": (0.90, 1.35, 2.37, 6.04)},
    "Voxelize into octree": {"Stanford bunny": (1.47, 3.43, 10.65, 42.61),
                             "Stanford dragon": (4.45, 9.59, 20.57, 55.36),
                             "XYZ RGB Asian dragon": (17.35, 17.96, 35.81, 82.55)},
    "Propagate inside/outside": {"Stanford bunny": (0.44, 1.36, 5.12, 19.71),
                                 "Stanford dragon": (0.32, 0.92, 3.28, 13.16),
                                 "XYZ RGB Asian dragon": (0.23, 0.56, 1.98, 7.54)},
    "Compute coverage factor": {"Stanford bunny": (0.12, 0.37, 1.37, 5.36),
                                "Stanford dragon": (0.10, 0.28, 1.02, 3.98),
                                "XYZ RGB Asian dragon": (0.07, 0.18, 0.60, 2.29)},
    "Stored level-0 nodes": {"Stanford bunny": (5.30, 2.71, 1.37, 0.69),
                             "Stanford dragon": (3.82, 2.00, 1.01, 0.51),
                             "XYZ RGB Asian dragon": (2.02, 1.10, 0.57, 0.29)},
    "Octree size": {"Stanford bunny": (3.2, 13.2, 53.7, 216),
                    "Stanford dragon": (2.3, 9.7, 39.6, 159),
                    "XYZ RGB Asian dragon": (1.2, 5.3, 22.3, 90.8)},
}

#: Zhang et al. 2018 Table 1: axis -> angle (degrees) -> ((comparisons, additions) of SS10,
#: of Pan11, of their method).
ZHANG_TABLE1 = {
    "y": {0: ((2483, 4966), (0, 0), (838, 1111)), 15: ((6356, 12712), (3806, 7612), (863, 1236)),
          30: ((8177, 16354), (5343, 10686), (1061, 1687)), 45: ((7835, 15666), (5523, 11046), (1027, 1744)),
          60: ((8151, 16302), (5246, 10492), (1068, 1701)), 75: ((6357, 12750), (3786, 7572), (863, 1236)),
          90: ((2483, 4966), (0, 0), (839, 1113))},
    "z": {0: ((2483, 4966), (0, 0), (838, 1111)), 15: ((5899, 11798), (3490, 6980), (863, 1236)),
          30: ((6204, 12408), (3940, 7880), (1061, 1687)), 45: ((8162, 16324), (5358, 10716), (1027, 1744)),
          60: ((6204, 12408), (3988, 7976), (1068, 1701)), 75: ((5899, 11798), (3502, 7004), (863, 1236)),
          90: ((2483, 4966), (0, 0), (839, 1113))},
}

#: Zhang et al. 2018 Table 2, the GPU column: model (triangles) -> grid size -> (Pan11 ms, their
#: integer scanline ms); 4096^3 did not fit the GPU.  Their meshes are not among the shared ones.
ZHANG_TABLE2_GPU: dict[str, dict[int, tuple[float, float]]] = {
    "Spider (3,341 tris)": {256: (0.30, 0.20), 512: (0.85, 0.45), 1024: (2.6, 1.1), 2048: (20.7, 8.6)},
    "Cambridge demon (8,822 tris)": {256: (0.82, 0.63), 512: (1.8, 1.5), 1024: (6.8, 4.2), 2048: (33.1, 19.5)},
    "Elephant (10,150 tris)": {256: (1.9, 1.8), 512: (4.1, 2.3), 1024: (15.4, 4.6), 2048: (85.4, 22.7)},
    "Sailboat (70,476 tris)": {256: (10.6, 4.3), 512: (17.9, 9.7), 1024: (48.8, 22.9), 2048: (160.8, 42.1)},
    "Dragon (100,000 tris)": {256: (1.3, 1.4), 512: (1.7, 1.6), 1024: (6.5, 5.2), 2048: (22.8, 17.5)},
}


def ss_model(mesh_name: str) -> str | None:
    """The Schwarz & Seidel model a shared mesh (file name) stands for, or None."""
    hit = SS_MODELS.get(mesh_name.rsplit("/", 1)[-1])
    return hit[0] if hit else None


def fmt(value, digits: int = 2) -> str:
    """A paper figure for a table cell: '-' where the paper has none."""
    if value is None:
        return "-"
    return f"{value:.{digits}f}" if isinstance(value, float) else f"{value}"
