"""Evaluation: detections scored against RLS's ground truth (box overlap, matching,
average precision), readers of other tools' detection files, and RLS's own roadside
detector. Boxes are ``Boxes`` (``detections.py``) in RLS's world frame."""
