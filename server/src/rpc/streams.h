// streams.h — the streaming calls' reactors, a file each: View
// (view_stream.cpp), Simulate (simulate_stream.cpp) and Tick
// (tick_stream.cpp). What they share (admission, raw messages, stopping,
// lifetime, the wake list's sink) is stream_reactor.h; they work with the
// layers beneath, Admission and Serving, never with the Service.
#pragma once

#include <grpcpp/grpcpp.h>

#include "serving/admission.h"
#include "serving/serving.h"

namespace voxvis::server {

/// A View stream: one viewer's frames (proto: Visibility.View; view_stream.cpp).
grpc::ServerBidiReactor<grpc::ByteBuffer, grpc::ByteBuffer>* new_view_stream(
    Admission& admission, Serving& serving, grpc::CallbackServerContext* ctx);
/// A Simulate stream: a backend's moves and the wake list (proto: Visibility.Simulate; simulate_stream.cpp).
grpc::ServerBidiReactor<grpc::ByteBuffer, grpc::ByteBuffer>* new_simulate_stream(
    Admission& admission, Serving& serving, grpc::CallbackServerContext* ctx);
/// A Tick stream: every viewer of a game server's tick (proto: Visibility.Tick; tick_stream.cpp).
grpc::ServerBidiReactor<grpc::ByteBuffer, grpc::ByteBuffer>* new_tick_stream(
    Admission& admission, Serving& serving, grpc::CallbackServerContext* ctx);

}  // namespace voxvis::server
