"""Dataset layouts detectors train on, written by a scan run (``rls dataset``).

``kitti``  OpenPCDet's custom-dataset layout (``kitti.KittiWriter``): per sensor
           ``points/NNNNNN.npy``, ``labels/NNNNNN.txt``, ``ImageSets/{train,val}.txt``
``opv2v``  OPV2V as OpenCOOD reads it (``opv2v.Opv2vWriter``): per scenario a folder
           per agent (every LiDAR), ``NNNNNN.pcd`` and ``NNNNNN.yaml`` per frame

Each is a writer of the scan run (``run.Writer``): checked before the first scan,
files written atomically as each scan ends, resumable, run-level files (splits) at the
end. ``docs/datasets.md`` states the frames and conventions.
"""

from ...choices import Choices

LAYOUTS = Choices("dataset layout", [
    ("kitti", "KITTI / OpenPCDet", "OpenPCDet's custom dataset: points .npy (or .bin), "
                                   "labels 'x y z dx dy dz heading class', ImageSets"),
    ("opv2v", "OPV2V / OpenCOOD", "OPV2V's folders per scenario and agent: .pcd (intensity "
                                  "in the colour channel) and .yaml (CARLA poses)"),
])
