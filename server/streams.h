// streams.h — the reactors of the View and Simulate streams (streams.cpp).
#pragma once

#include <memory>

#include <grpcpp/grpcpp.h>

#include "service.h"

namespace voxvis::server {

/// A View stream: one viewer's frames (proto: Visibility.View).
grpc::ServerBidiReactor<grpc::ByteBuffer, grpc::ByteBuffer>* new_view_stream(
    Service* svc, grpc::CallbackServerContext* ctx);
/// A Simulate stream: a backend's moves and the wake list (proto: Visibility.Simulate).
grpc::ServerBidiReactor<grpc::ByteBuffer, grpc::ByteBuffer>* new_simulate_stream(
    Service* svc, grpc::CallbackServerContext* ctx);
/// A Tick stream: every viewer of a game server's tick (proto: Visibility.Tick; tick_stream.cpp).
grpc::ServerBidiReactor<grpc::ByteBuffer, grpc::ByteBuffer>* new_tick_stream(
    Service* svc, grpc::CallbackServerContext* ctx);

}  // namespace voxvis::server
