"""Training: the loop (``train``: ``train``, ``TrainState``), its validation and previews
(``validate``), distillation of fitted latents (``distill``), the outline loss's targets
(``outline``), and the networks trained beside a model: the segment-count predictor (``aux``)
and the feature net of the sample-quality metric (``features``). Imported by module (torch
starts with them); ``api.train``, ``api.train_aux`` and ``api.train_features`` are the doors.
"""
