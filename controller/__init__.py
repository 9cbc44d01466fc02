"""What users run: AU frames, inputs, expressions, timelines, the pipeline, its fixed-rate loop, the CLI."""
