"""The thesis's message crossover (§4.1.6–4.1.7), shared by bench/classic.sh's table and
bench/classic_plot.py: classic shadow rays with every occupied voxel emitting cost
(messages per ray) × (occupancy · n³) × (sources) link messages, diffusion's cost does not
depend on the occupancy, so diffusion sends fewer messages above the occupancy where the two
are equal."""


def crossover(diffusion, classic_all, n):
    """(messages per classic ray, the occupancy % above which diffusion wins) from the two runs'
    rows of bench-out/classic.csv at grid side n."""
    per = int(classic_all["messages"]) / max(1, int(classic_all["rays"]))
    # Every voxel facing a light emits one ray per such light (those facing away emit none).
    sources = max(1, round(int(classic_all["rays"]) / max(1, int(classic_all["voxels"]))))
    return per, 100.0 * int(diffusion["messages"]) / (per * n**3 * sources)
