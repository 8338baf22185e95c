//! Features from pixels: board corners and poses in the photos, the camera's
//! calibration, the hemisphere's arc, compact echoes, N-wire dots and a flat
//! reflector's line in the B-scans.
pub mod arc;
pub mod aruco;
pub mod aruco_pose;
pub mod board;
pub mod board_grid;
pub mod board_pose;
pub mod camera_calibration;
pub mod camera_refinement;
pub mod charuco_calibration;
pub mod charuco_pose;
pub mod circle;
pub mod corners;
pub mod fan;
pub mod line;
pub mod nwire;
pub mod overlay;
pub mod projection;
pub mod ridge;
pub mod rig_pose;
pub mod spot;
