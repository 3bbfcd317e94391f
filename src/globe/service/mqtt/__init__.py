"""Home Assistant over MQTT: :mod:`.payloads` (what is published: discovery and states, pure),
:mod:`.statestream` (Home Assistant's states read into observations, pure) and :mod:`.bridge`
(the paho-mqtt client started with the service when ``[mqtt] enabled = true``)."""
