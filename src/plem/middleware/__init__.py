"""ROS 2 over Cyclone DDS without ROS: interface types, names, QoS, discovery, nodes and actions."""

from plem.middleware.action import ActionClient, ActionServer
from plem.middleware.discovery import DiscoverySettings
from plem.middleware.node import Node, Publisher, ServiceClient, ServiceServer, Subscription
from plem.middleware.qos import QosProfile
from plem.middleware.types import InterfaceLibrary, library

__all__ = ["ActionClient", "ActionServer", "DiscoverySettings", "InterfaceLibrary", "Node", "Publisher", "QosProfile",
           "ServiceClient", "ServiceServer", "Subscription", "library"]
