"""General estimation, free of GNSS specifics: Kalman filters (KF/EKF/CKF/square-root CKF) in ``filters``."""
