"""Training: the GRU, GRAD models, baselines, REMA tuning, ONNX export."""
