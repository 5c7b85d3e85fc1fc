"""Jobs: the pipeline API (jobs/pipeline.py), the command line that maps arguments onto it
(the package jobs/cli/), and the job run in a background process for Blender's interface."""
