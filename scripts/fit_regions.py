"""X = R11^-1 R12 for k main markers, region maps and orthogonal-direction maps (Figs. 4-7)."""

from facemotion.ingest.displacement_file import load_displacements
from facemotion.ingest.displacements import split_roles
from facemotion.plots.face_mesh import read_face_mesh
from facemotion.plots.regions import plot_orthogonal_directions, plot_region_maps
from facemotion.ranking.routes import rank_for_study
from facemotion.regions.prediction import fit_coefficients
from facemotion.study.adapter import run_step
from facemotion.study.outputs import figure_files
from facemotion.study.provenance import save_figure, write_table


def main(sm, log, prov):
    d = load_displacements(sm.input.npz)
    train, _ = split_roles(d, sm.input.sentences)
    k = int(sm.wildcards.k)
    ranking = rank_for_study(train.A, train.labels, method=sm.params.method,
                             k_max=sm.params.k_max)
    X = fit_coefficients(ranking, k)
    table = X.copy()
    table.insert(0, "main_marker", X.index.astype(str))
    write_table(table, sm.output.table, "coefficients", prov)
    mesh = read_face_mesh(sm.input.mesh[0], sm.params.mesh_labels) if sm.input.mesh else None
    if mesh is not None:
        log.info("maps drawn on the face mesh %s (%d vertices)", sm.input.mesh[0],
                 len(mesh.vertices))
    fig = plot_region_maps(d.neutral, d.labels, X, grid_n=sm.params.grid_n, mesh=mesh)
    save_figure(fig, figure_files(sm.output, "png"), "regions", prov)
    fig = plot_orthogonal_directions(d.neutral, d.labels, ranking.R,
                                     ranking.labels_in_order,
                                     n_pivots=sm.params.orthogonal_maps,
                                     grid_n=sm.params.grid_n, mesh=mesh)
    save_figure(fig, figure_files(sm.output, "orth_png"), "orthogonal_directions", prov)


run_step(snakemake, main)  # noqa: F821
