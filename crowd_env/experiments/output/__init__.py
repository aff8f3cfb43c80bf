"""Output of the commands: ``video`` (MP4/GIF of a rollout or a trajectory file) and ``tables`` (one table
renderer, plain text or Markdown), ``evaluation_report`` (the harness's results as tables, CSV, a chart)."""
