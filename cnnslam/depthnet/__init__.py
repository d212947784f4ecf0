"""The depth + semantic CNN of CNN-SLAM (Sec. 3.2): an FCRN-style network (Laina et al. 2016) trained from scratch on
the simulator's training split, with shipped default weights.

Public API (``cnnslam.depthnet.predict``): :class:`Prediction`, :class:`DepthNetPredictor` (``predict_raw`` = the
network's depth, ``predict`` = depth for the current camera by CNN-SLAM eq. 5) and ``load_predictor(weights=None)``
(None = ``weights/default.pt``). Modules: ``model`` (network), ``loss`` (berHu, cross-entropy), ``data`` (training
data to disk, dataset, augmentation), ``train`` (loop), ``metrics`` / ``validate`` / ``report`` / ``plots`` (the
validation report), ``bench`` (inference speed), ``cli_train`` (``cnnslam train``). Submodules are imported on
demand, so ``import cnnslam.depthnet`` stays cheap.
"""
