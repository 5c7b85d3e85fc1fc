"""The benchmark's sections, one module each; scripts/bench.py runs them and writes
bench/results.json and bench/results.md (docs/testing.md, "Benchmark").

Each section module has ``bench_<section>(quick, work) -> dict`` (its part of results.json;
``work`` a temporary folder) and ``<section>_table(section) -> list`` (its lines of
results.md): render_time, equal_error, main_job, bake, scene_transport, task_graph,
scene_real, scene_cost, scene_samples, scene_depth, material_files. What they share (the
renderers, one render in a child process) is common.py.
"""
