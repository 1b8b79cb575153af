"""The trajectory picture and the camera recorder write real files that read back."""
import cv2
import numpy as np

from pilotlab.circuits.load import get_circuit
from pilotlab.online.media import CameraRecorder, plot_trajectories
from pilotlab.online.trajectory import Trajectory


def lap_of(circuit, lateral: float, termination: str, fraction: float = 1.0) -> Trajectory:
    s = np.linspace(0, circuit.length * fraction, 200)
    x, y, _ = np.array([circuit.start_pose(v, lateral) for v in s]).T
    n = len(s)
    return Trajectory(t=s / 8, wall=s / 80, x=x, y=y, yaw=np.zeros(n), speed=np.linspace(2, 12, n), progress=s,
                      lateral=np.full(n, lateral), off_road=np.zeros(n, bool), v=np.ones(n), w=np.zeros(n),
                      brain_s=np.ones(n), inference_s=np.ones(n), charged_s=np.zeros(n),
                      circuit_length=circuit.length, meta={"termination": termination})


def test_the_trajectory_picture_shows_runs_over_the_circuit(tmp_path):
    circuit = get_circuit("simple_circuit")
    runs = [lap_of(circuit, 0.5, "lap_completed"), lap_of(circuit, -3.5, "off_road", 0.3)]
    path = plot_trajectories(circuit, runs, tmp_path / "trajectory.png", title="two runs")
    image = cv2.imread(str(path))
    assert image is not None and min(image.shape[:2]) > 300
    # The speed colour map (plasma) shows up: a yellowish fast end and a purple slow start.
    hsv = cv2.cvtColor(image, cv2.COLOR_BGR2HSV)
    assert np.count_nonzero((hsv[..., 0] > 125) & (hsv[..., 0] < 150) & (hsv[..., 1] > 120)) > 50


def test_the_camera_recorder_holds_each_image_for_as_long_as_the_brain_took(tmp_path):
    recorder = CameraRecorder(tmp_path, control_hz=20.0, video_seconds=1.0, stills=3)
    image = np.zeros((120, 160, 3), np.uint8)
    for t in (0.0, 0.05, 0.1, 0.25, 0.5, 1.0, 1.5, 2.0, 2.5):    # a brain that slows down
        recorder(image, {"sim_time": t}, (5.0, 0.1))
    written = recorder.close()
    assert written["video"] == "camera.mp4" and len(written["camera_frames"]) == 3
    video = cv2.VideoCapture(str(tmp_path / "camera.mp4"))
    assert int(video.get(cv2.CAP_PROP_FRAME_COUNT)) == 21        # 0 .. 1.0 s at 20 frames per second
    assert all((tmp_path / name).stat().st_size > 0 for name in written["camera_frames"])
    assert written["camera_frames"][0] == "frames/camera_000.00s.jpg"


def test_the_picture_title_names_a_bm_world():
    """Outside test: the pictures of BM's simple_circuit and its white_line variant had one title."""
    from pilotlab.online.evaluate import picture_title
    from pilotlab.specs.online import OnlineSpec
    in_world = OnlineSpec(circuit="simple_circuit", world="simple_circuit_white_line")
    assert picture_title("explicit", in_world, {}, 1).startswith("explicit in BM's world simple_circuit_white_line (cw)")
    assert picture_title("explicit", OnlineSpec(circuit="simple_circuit"), {}, 1).startswith("explicit on simple_circuit (cw)")
