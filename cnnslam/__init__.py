"""CNN-SLAM (Tateno, Tombari, Laina, Navab, CVPR 2017): monocular dense SLAM with CNN depth prediction.

One module per stage of the paper's Fig. 2; see README.md for the layout. This package never sees ground truth.
"""

__version__ = "0.1.0"
