"""CNN depth prediction for key-frames (CNN-SLAM Sec. 3.2-3.3): the predictor contract and eq. 5's focal adjustment."""
