# The compiled build's C types for these classes: their attributes in slots (setup.py, tests/test_pxd.py); the
# broker's methods a message passes through take its client as a MockClient, so they read its slots directly

cimport cython

cdef class MockBroker

cdef class MockClient:
    cdef dict __dict__
    cdef object __weakref__
    cdef public object _broker, client_id, will, up, down, keepalive_s, on_connect, _subs, _connected, _conn
    cdef public object _cuts, _last_up_s, _last_down_s, _deadline, _pinger

    @cython.locals(broker=MockBroker)
    cpdef publish(self, topic, payload, retain=*, qos=*)

cdef class MockBroker:
    cdef dict __dict__
    cdef object __weakref__
    cdef public object scheduler, _rng, _clients, _routes, _retained, running
    cdef public object last_error, stats

    cpdef _heard(self, MockClient client, cuts)
    cpdef _delay(self, link, last_s)
    cpdef _arrivals(self, link, last_s)
    cpdef _from_client(self, MockClient client, topic, payload, retain)
    cpdef _arrive(self, MockClient client, cuts, topic, payload, retain)
    cpdef _to_client(self, MockClient client, topic, payload)
    cpdef _deliver(self, MockClient client, conn, topic, payload)
