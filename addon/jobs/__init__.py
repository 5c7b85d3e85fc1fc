"""Jobs: the pipeline API (jobs/pipeline.py), the command line that maps arguments onto it
(jobs/cli.py), and the job run in a background process for Blender's interface."""
