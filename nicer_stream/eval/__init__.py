"""Evaluation: trajectory (ATE/RPE), image (PSNR/SSIM/depth L1) and mesh metrics,
and `evaluate_output_dir` (nicer_stream.eval.evaluate) for a run's output directory."""
