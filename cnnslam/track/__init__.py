"""Camera pose estimation (CNN-SLAM Sec. 3.1, eq. 1-4): direct photometric tracking on an image pyramid."""
