"""Key-frames (CNN-SLAM Sec. 3.3-3.4, eq. 6-11): selection, uncertainty, fusion and frame-wise epipolar refinement."""
