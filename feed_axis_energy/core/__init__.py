"""Pure numerical core: never imports rclpy or any ``*_msgs`` package.

Data flows one way: program (:mod:`.gcode`) -> sampled motion (:mod:`.trajectory`)
-> forces, torques and speeds (:mod:`.dynamics`) -> power and energy (:mod:`.energy`).
"""
