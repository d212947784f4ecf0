"""The key-frame pose graph (CNN-SLAM Sec. 3.3) and its optimisation."""
