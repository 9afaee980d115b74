"""Start the artformer generator node with the package's parameter file.

    ros2 launch artformer_ros artformer.launch.py [params_file:=my.yaml] [namespace:=gen]
        [remap_description:=artformer/robot_description] [remap_joint_states:=/joint_states]

Every node parameter (backend, output_dir, frame_id, openness, animate...) comes from the
params file; copy share/artformer_ros/config/artformer.yaml, edit it and pass it as
params_file. Its key `/**` matches the node in any namespace.

Needs a full ROS 2 install (the `launch` and `launch_ros` packages). Topics are relative, so
`namespace` moves all of them; `remap_description` and `remap_joint_states` rename the two
topics that robot_state_publisher also knows (a relative target stays in the namespace, a
leading `/` makes it global).
"""
import os

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node


def generate_launch_description():
    share = get_package_share_directory("artformer_ros")
    default_params = os.path.join(share, "config", "artformer.yaml")
    args = [
        DeclareLaunchArgument("params_file", default_value=default_params,
                              description="YAML file with the node's parameters"),
        DeclareLaunchArgument("namespace", default_value="",
                              description="namespace of the node and its topics"),
        DeclareLaunchArgument("remap_description", default_value="robot_description",
                              description="topic the URDF is latched on"),
        DeclareLaunchArgument("remap_joint_states", default_value="joint_states",
                              description="topic of the object's joint positions"),
    ]
    node = Node(
        package="artformer_ros",
        executable="artformer_generator_node",
        name="artformer_generator",
        namespace=LaunchConfiguration("namespace"),
        output="screen",
        emulate_tty=True,
        parameters=[LaunchConfiguration("params_file")],
        remappings=[("robot_description", LaunchConfiguration("remap_description")),
                    ("joint_states", LaunchConfiguration("remap_joint_states"))],
    )
    return LaunchDescription(args + [node])
