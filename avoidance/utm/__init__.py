"""UTM side of the rules of the air (spec §7.1-7.4): position notifications, collision cases,
case chaining and the roundabout merge."""
