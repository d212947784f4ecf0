"""The global model and semantic label fusion (CNN-SLAM Sec. 3.5): surfels, their store and kernels, projective ICP
against the model's maps, export and pictures."""
