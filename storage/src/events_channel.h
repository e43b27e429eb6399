// Private to ambdiag_storage: the PostgreSQL channel append_event NOTIFYs
// and EventListener LISTENs on, as SQL of the session's schema: one channel
// per historian, so a historian in another schema of the database (a
// test's, another plant's) never wakes this one's readers. md5 keeps the
// name under PostgreSQL's 63 bytes whatever the schema's name.
#pragma once

#define AMBDIAG_EVENTS_CHANNEL_SQL "('ambdiag_events_' || md5(current_schema()))"
